#pragma once
// The thread of one of the editor's services (ui/session_runner.h): one iteration after
// another, sleeping after an iteration that did nothing until wake() or a timeout.

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace penumbra {

class ServiceThread {
public:
    ServiceThread() = default;
    /// Stops the thread (stop()).
    ~ServiceThread();
    ServiceThread(const ServiceThread&) = delete;
    ServiceThread& operator=(const ServiceThread&) = delete;

    /// Runs `iterate` on a thread named `name` (core/thread_priority.h) at `nice`; after an
    /// iteration that returns false it sleeps until wake() or for `idle`. Nothing when running.
    /// At a positive nice (a background service: the solver, the holodeck) the iteration's
    /// parallel work runs in a low-priority oneTBB arena, so the worker threads every service
    /// shares serve the render thread's frames first.
    void start(const char* name, int nice, std::chrono::milliseconds idle,
               std::function<bool()> iterate);
    /// Lets the iteration in progress finish and joins the thread.
    void stop();
    /// Ends the current sleep, or the next one.
    void wake();
    bool running() const { return mThread.joinable(); }

private:
    std::mutex mMutex;
    std::condition_variable mWake;
    bool mStop = false;
    bool mWoken = false;
    std::thread mThread;
};

}  // namespace penumbra
