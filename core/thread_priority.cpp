#include "core/thread_priority.h"

#include <algorithm>

#ifdef __linux__
#include <pthread.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace penumbra {

void lowerThreadPriority(int nice) {
#ifdef __linux__
    if (nice <= 0) return;
    const auto tid = static_cast<id_t>(syscall(SYS_gettid));
    const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(getpid()));
    (void)setpriority(PRIO_PROCESS, tid, std::min(19, base + nice));
#else
    (void)nice;
#endif
}

void nameThisThread(const char* name) {
#ifdef __linux__
    char shortName[16] = {};
    for (int i = 0; i < 15 && name[i]; ++i) shortName[i] = name[i];
    (void)pthread_setname_np(pthread_self(), shortName);
#else
    (void)name;
#endif
}

}  // namespace penumbra
