#include "apps/ranks.h"

#include <cstdlib>
#include <memory>
#include <string>

#include "specula/core/error.h"

#ifdef SPECULA_MPI
#include <mpi.h>
#endif

namespace specula::app {
namespace {

#ifdef SPECULA_MPI
class MpiWorld final : public Collective {
 public:
  MpiWorld() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void allgather(std::span<const double> mine, std::span<double> all) const override {
    if (all.size() != mine.size() * std::size_t(size_))
      throw UsageError("allgather: output must hold size() * input values");
    check(MPI_Allgather(mine.data(), int(mine.size()), MPI_DOUBLE, all.data(), int(mine.size()), MPI_DOUBLE,
                        MPI_COMM_WORLD),
          "MPI_Allgather");
  }

 private:
  static void check(int code, const char* what) {
    if (code == MPI_SUCCESS) return;
    char text[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(code, text, &len);
    throw LibraryError(std::string(what) + ": " + std::string(text, std::size_t(len)));
  }
  int rank_ = 0, size_ = 1;
};

std::unique_ptr<MpiWorld> world;

// Launchers set these (Open MPI's mpirun, PMIx and PMI-2 launchers such as Slurm's srun).
bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(v)) return true;
  return false;
}
#endif

}  // namespace

void start_ranks([[maybe_unused]] int& argc, [[maybe_unused]] char**& argv) {
#ifdef SPECULA_MPI
  if (!launched_by_mpi()) return;
  int provided = 0;
  // Collectives are called from the main thread only, between OpenMP regions.
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  world = std::make_unique<MpiWorld>();
#endif
}

void stop_ranks() {
#ifdef SPECULA_MPI
  if (world) {
    world.reset();
    MPI_Finalize();
  }
#endif
}

const Collective& ranks() {
#ifdef SPECULA_MPI
  if (world) return *world;
#endif
  return single_process();
}

void abort_ranks([[maybe_unused]] int code) {
#ifdef SPECULA_MPI
  if (world && world->size() > 1) MPI_Abort(MPI_COMM_WORLD, code);
#endif
}

std::string rank_prefix() {
  const Collective& c = ranks();
  return c.size() > 1 ? "rank " + std::to_string(c.rank()) + " of " + std::to_string(c.size()) + ": " : "";
}

}  // namespace specula::app
