#include "core/thread_priority.h"

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace penumbra {

void lowerThreadPriority(int nice) {
#ifdef __linux__
    if (nice <= 0) return;
    const auto tid = static_cast<id_t>(syscall(SYS_gettid));
    (void)setpriority(PRIO_PROCESS, tid, getpriority(PRIO_PROCESS, tid) + nice);
#else
    (void)nice;
#endif
}

}  // namespace penumbra
