// ThreadSanitizer builds only (PENUMBRA_TSAN): oneTBB runs every parallel loop on the calling
// thread. Debian's oneTBB is not instrumented, so the ordering its own synchronization gives
// (a loop's writes before the code after the loop) is invisible to TSan and would be reported
// as races; on one thread there is none to see, and what TSan checks are Penumbra's own threads.

#include <tbb/global_control.h>

namespace {

const tbb::global_control kOneThread(tbb::global_control::max_allowed_parallelism, 1);

}  // namespace
