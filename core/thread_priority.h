#pragma once
// Scheduling priority of the calling thread.

namespace penumbra {

/// Lowers the calling thread's scheduling priority by `nice` (a Linux nice increment; nothing
/// for nice ≤ 0 or elsewhere): background threads (the editor's solver, render, build and
/// shading threads) yield the cores to the UI thread, so frames keep their rate on a loaded
/// machine.
void lowerThreadPriority(int nice);

/// Names the calling thread (at most 15 characters; Linux shows it in top -H, ps -L and
/// debuggers), nothing elsewhere.
void nameThisThread(const char* name);

}  // namespace penumbra
