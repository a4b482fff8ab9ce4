#pragma once
// The ranks of an `mpirun` job, for `penumbra holodeck fill` (docs/holodeck.md, "Scale-out").
// The only Penumbra header about MPI, and it names no MPI type: mpi.h stays inside
// app/mpi_world.cpp, so no other translation unit sees it. MPI is initialised only in a process
// that mpirun started; everywhere else (a plain run, the tests, the sanitizer runs) this is a
// world of one rank and no MPI call is made.
//
// Index: launchedByMpirun · MpiWorld

#include <cstdint>
#include <string>

namespace penumbra {

/// True when mpirun (Open MPI, or any PMIx launcher) started this process: its environment
/// holds OMPI_COMM_WORLD_SIZE or PMIX_RANK.
bool launchedByMpirun();

/// MPI_COMM_WORLD for the lifetime of the object: MPI_Init in the constructor when
/// launchedByMpirun(), MPI_Finalize in the destructor. Every collective call below must be made
/// by every rank in the same order. Not copyable; one per process.
class MpiWorld {
public:
    MpiWorld();
    ~MpiWorld();
    MpiWorld(const MpiWorld&) = delete;
    MpiWorld& operator=(const MpiWorld&) = delete;

    /// Whether MPI was initialised (false: one rank, no MPI).
    bool active() const { return mActive; }
    int rank() const { return mRank; }
    int size() const { return mSize; }
    /// Ranks on this machine (OMPI_COMM_WORLD_LOCAL_SIZE; 1 when unknown).
    int localSize() const { return mLocalSize; }

    /// Collective: the lowest rank whose `failed` is true, or -1 when none is. Every phase of a
    /// job ends with one, so that a rank that fails never leaves the others waiting.
    int lowestFailing(bool failed) const;
    /// Collective: the sum and the maximum over the ranks.
    std::int64_t sum(std::int64_t value) const;
    double max(double value) const;
    /// Ends every rank of the job with `code` (MPI_Abort; std::exit when not active): for a
    /// failure the other ranks cannot be told about collectively.
    [[noreturn]] void abort(int code) const;

private:
    bool mActive = false;
    int mRank = 0, mSize = 1, mLocalSize = 1;
};

}  // namespace penumbra
