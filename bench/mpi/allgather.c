/* Latency of the one collective specula's ranks use: MPI_Allgather of n doubles per rank, averaged over many
   rounds after a warm-up. Usage: mpirun -np P allgather N ROUNDS; prints one JSON line from rank 0. */
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const int n = argc > 1 ? atoi(argv[1]) : 224, rounds = argc > 2 ? atoi(argv[2]) : 20000;
  double* mine = calloc((size_t)n, sizeof(double));
  double* all = calloc((size_t)n * (size_t)size, sizeof(double));
  for (int i = 0; i < 1000; ++i) MPI_Allgather(mine, n, MPI_DOUBLE, all, n, MPI_DOUBLE, MPI_COMM_WORLD);
  MPI_Barrier(MPI_COMM_WORLD);
  const double t0 = MPI_Wtime();
  for (int i = 0; i < rounds; ++i) MPI_Allgather(mine, n, MPI_DOUBLE, all, n, MPI_DOUBLE, MPI_COMM_WORLD);
  const double t = (MPI_Wtime() - t0) / rounds;
  if (rank == 0) printf("{\"ranks\":%d,\"doubles\":%d,\"seconds\":%.9f}\n", size, n, t);
  free(mine);
  free(all);
  MPI_Finalize();
  return 0;
}
