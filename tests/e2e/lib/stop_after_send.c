/* stop_after_send.c: helper of tests/e2e/render_tracer_stop_large.sh (built
 * by it with mpicc, loaded into every rank with LD_PRELOAD). The rank named
 * by CORRTEX_STOP_RANK stops itself (SIGSTOP) right after MPI_Isend has
 * started its CORRTEX_STOP_AFTER-th message of at least 64 KiB to rank 0:
 * the master then has a large message in flight from a stopped sender, at
 * an exact point rather than when a kill from outside happens to land
 * there. Every call goes on to the real MPI (PMPI_Isend). */
#include <mpi.h>
#include <signal.h>
#include <stdlib.h>

int MPI_Isend(const void *buf, int count, MPI_Datatype type, int dest, int tag, MPI_Comm comm, MPI_Request *req)
{
    static int large;
    int rc = PMPI_Isend(buf, count, type, dest, tag, comm, req);
    const char *who = getenv("CORRTEX_STOP_RANK"), *after = getenv("CORRTEX_STOP_AFTER");
    int rank = -1, size = 0;
    PMPI_Comm_rank(comm, &rank);
    PMPI_Type_size(type, &size);
    if (who && after && rank == atoi(who) && dest == 0 && (long)count * size >= 65536 && ++large == atoi(after))
        raise(SIGSTOP);
    return rc;
}
