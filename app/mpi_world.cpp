#include "app/mpi_world.h"

// The C API only: Open MPI's deprecated C++ bindings stay out.
#define OMPI_SKIP_MPICXX 1
#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <exception>
#include <thread>

namespace penumbra {

namespace {

/// An allreduce over MPI_COMM_WORLD that waits asleep: a blocking one spins a core at full
/// speed until the last rank arrives, and the ranks that wait (for the slowest fill, for rank
/// 0's merge) share the machine with the ones still working.
void allreduce(const void* in, void* out, MPI_Datatype type, MPI_Op op) {
    MPI_Request request;
    MPI_Iallreduce(in, out, 1, type, op, MPI_COMM_WORLD, &request);
    for (int done = 0;;) {
        MPI_Test(&request, &done, MPI_STATUS_IGNORE);
        if (done) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

}  // namespace

bool launchedByMpirun() {
    return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMIX_RANK") != nullptr;
}

MpiWorld::MpiWorld() {
    if (!launchedByMpirun()) return;
    MPI_Init(nullptr, nullptr);
    mActive = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &mRank);
    MPI_Comm_size(MPI_COMM_WORLD, &mSize);
    if (const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE"))
        mLocalSize = std::max(1, std::atoi(local));
    // An exception nobody catches ends the whole job rather than leaving the other ranks
    // waiting in a collective call.
    std::set_terminate([] {
        MPI_Abort(MPI_COMM_WORLD, 2);
        std::abort();
    });
}

MpiWorld::~MpiWorld() {
    if (mActive) MPI_Finalize();
}

int MpiWorld::lowestFailing(bool failed) const {
    if (!mActive) return failed ? 0 : -1;
    int mine = failed ? mRank : mSize, lowest = mSize;
    allreduce(&mine, &lowest, MPI_INT, MPI_MIN);
    return lowest < mSize ? lowest : -1;
}

std::int64_t MpiWorld::sum(std::int64_t value) const {
    if (!mActive) return value;
    std::int64_t total = 0;
    allreduce(&value, &total, MPI_INT64_T, MPI_SUM);
    return total;
}

double MpiWorld::max(double value) const {
    if (!mActive) return value;
    double most = 0;
    allreduce(&value, &most, MPI_DOUBLE, MPI_MAX);
    return most;
}

void MpiWorld::abort(int code) const {
    if (mActive) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
}

}  // namespace penumbra
