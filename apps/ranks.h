#pragma once
// The processes of one specula run. In a SPECULA_MPI build launched by mpirun or srun these are MPI's world
// ranks; otherwise the run is one process. Libraries see only core/collective.h.
#include <string>

#include "specula/core/collective.h"

namespace specula::app {

/// Joins MPI when this SPECULA_MPI build was started by an MPI launcher; else does nothing.
void start_ranks(int& argc, char**& argv);
/// Leaves MPI after a successful run.
void stop_ranks();
/// The processes of this run (single_process() unless MPI was joined).
const Collective& ranks();
/// After an error on this rank, stops every rank of the run with `code` (MPI_Abort); returns when one process.
void abort_ranks(int code);
/// "rank R of N: " when several processes run, else "".
std::string rank_prefix();

}  // namespace specula::app
