// terralod build under MPI (mpirun -np N terralod build ...): every rank reads the input; rank 0
// opens the database, builds blocks on its threads and hands the rest out one at a time to the
// other ranks' threads, writes every block in its own transaction and then the tree, exactly as
// a single-process build (blocks::build_database with a RemoteBuilder), so the database is the
// same block for block, byte for byte. Only rank 0 touches the database: nothing assumes a
// shared folder beyond the input (which every rank reads) and the output (which only rank 0
// writes); the cost is one message per block (its encoded PM, about 3 bytes a sample) to rank 0.
// A killed rank ends the job (mpirun aborts the others); the database keeps every block written
// and the same command resumes it. Rank 0 shows the progress with the time left.
//
// Compiled only when CMake finds MPI (TERRALOD_HAVE_MPI); without mpirun (or with one rank)
// terralod build runs as a single process.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>

#include "terralod/blocks/tree_builder.hpp"

namespace terralod::cli {

/// Ranks in the job this process was started in by mpirun (Open MPI, MPICH or a PMIx launcher;
/// 1 when not started by one). Reads the launcher's environment; initializes nothing.
inline int launched_ranks() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"})
    if (const char* s = std::getenv(v)) return std::max(1, std::atoi(s));
  return 1;
}
/// This process's rank in that job (0 when not started by a launcher).
inline int launched_rank() {
  for (const char* v : {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"})
    if (const char* s = std::getenv(v)) return std::max(0, std::atoi(s));
  return 0;
}

/// Runs the build as rank `rank` of the job (MPI is initialized and finalized here). `read`
/// reads the terrain (every rank calls it), `report` prints rank 0's summary. Returns the exit
/// status; any error on any rank aborts the whole job with its message.
int build_with_mpi(
    const std::function<std::unique_ptr<blocks::DemSource>()>& open, const std::string& out,
    blocks::DatabaseBuildOptions options,
    const std::function<void(const blocks::DatabaseSummary&, int ranks, const blocks::DemSource&)>& report);

}  // namespace terralod::cli
