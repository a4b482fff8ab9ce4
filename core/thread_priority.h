#pragma once
// Scheduling priority of the calling thread.

namespace penumbra {

/// Sets the calling thread's scheduling priority `nice` steps below the process's main thread
/// (a Linux nice value relative to it, whatever the thread inherited from the one that made it;
/// nothing for nice ≤ 0 or elsewhere): background threads (the editor's solver, build and
/// shading threads) yield the cores to the UI and render threads, so the window and its lit
/// images keep their rate on a loaded machine.
void lowerThreadPriority(int nice);

/// Names the calling thread (at most 15 characters; Linux shows it in top -H, ps -L and
/// debuggers), nothing elsewhere.
void nameThisThread(const char* name);

}  // namespace penumbra
