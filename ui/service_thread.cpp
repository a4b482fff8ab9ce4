#include "ui/service_thread.h"

#include <tbb/task_arena.h>

#include "core/thread_priority.h"

namespace penumbra {

ServiceThread::~ServiceThread() { stop(); }

void ServiceThread::start(const char* name, int nice, std::chrono::milliseconds idle,
                          std::function<bool()> iterate) {
    if (mThread.joinable()) return;
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mStop = false;
    }
    mThread = std::thread([this, name, nice, idle, iterate = std::move(iterate)] {
        nameThisThread(name);
        lowerThreadPriority(nice);
        // A background thread's parallel work (oneTBB) runs in a low-priority arena: the
        // worker threads all services share take the render thread's work first.
        tbb::task_arena arena(
            tbb::task_arena::automatic, 1,
            nice > 0 ? tbb::task_arena::priority::low : tbb::task_arena::priority::normal);
        for (;;) {
            const bool worked = arena.execute([&] { return iterate(); });
            std::unique_lock<std::mutex> lock(mMutex);
            if (mStop) return;
            if (!worked) mWake.wait_for(lock, idle, [&] { return mStop || mWoken; });
            mWoken = false;
            if (mStop) return;
        }
    });
}

void ServiceThread::stop() {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mStop = true;
    }
    mWake.notify_all();
    if (mThread.joinable()) mThread.join();
}

void ServiceThread::wake() {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mWoken = true;
    }
    mWake.notify_all();
}

}  // namespace penumbra
