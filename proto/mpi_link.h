/* mpi_link.h: the MPI transport between the master (rank 0) and the tracer
 * ranks: start-up and shutdown, non-blocking sends of encoded byte buffers
 * (proto/wire_mpi.h layouts) under a tag, receiving whole messages without
 * ever blocking on a peer, and a chunked broadcast for large payloads (the
 * radiosity mesh). The only file of the project that includes <mpi.h>: proto owns every
 * wire, MPI included, so that tracer/ and master/ stay MPI-free and testable.
 * Every MPI call goes through one check that turns a failure into a ct_error
 * naming file:line, the call and MPI's error string. */
#ifndef CT_PROTO_MPI_LINK_H
#define CT_PROTO_MPI_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "proto/wire.h"

/* Message tags (explicit values: they cross the wire). */
typedef enum mpil_tag {
    MPIL_TAG_REQUESTS = 11,  /* master -> tracer: WIRE_MPI_REQUESTS */
    MPIL_TAG_SAMPLES  = 12,  /* tracer -> master: WIRE_MPI_SAMPLES */
    MPIL_TAG_CAMERA   = 13,  /* master -> tracers: WIRE_MPI_CAMERA */
    MPIL_TAG_CONTROL  = 14,  /* master -> tracers: WIRE_MPI_CONTROL */
    MPIL_TAG_BYE      = 15   /* tracer -> master: the tracer is leaving (empty) */
} mpil_tag;

#define MPIL_ANY (-1)                       /* any source or any tag */
#define MPIL_BCAST_CHUNK ((size_t)16 << 20) /* bytes per broadcast step */
#define MPIL_MAX_MESSAGE ((size_t)1 << 30)  /* largest point-to-point message */

/* What mpil_probe found. */
typedef struct mpil_info {
    int source;
    int tag;
    size_t size;
} mpil_info;

/* Starts MPI (thread level FUNNELED: only the main thread calls MPI), makes
 * errors return instead of aborting, and reports rank and size. */
int mpil_init(int *argc, char ***argv, int *rank, int *size, ct_error *err);

/* This process' host name as MPI reports it. */
void mpil_host(char *out, size_t cap);

/* Ends MPI after the pending sends completed (0), or fails naming the call. */
int mpil_finalize(ct_error *err);

/* Ends the whole job at once (every rank) with an exit code: for a master
 * that cannot go on and cannot reach the tracers in order. */
void mpil_abort(int code);

/* Starts a send of buf's bytes and takes the buffer over (buf is zeroed); the
 * memory is released once the send completed (mpil_progress). */
int mpil_isend(int dest, int tag, wire_buf *buf, ct_error *err);

/* Completes finished non-blocking sends; returns how many are still pending
 * (>= 0) or a negative error. */
int mpil_progress(ct_error *err);

/* Waits up to timeout_s for every pending send; CT_EIO when some are still
 * pending then (a peer that stopped receiving). */
int mpil_drain(double timeout_s, ct_error *err);

/* Cancels what is still pending (after a failed drain) so MPI can end. */
void mpil_cancel_pending(void);

/* Receives the next whole message from source with tag (MPIL_ANY) without
 * ever blocking: every message that arrived is matched (MPI_Improbe) and
 * its receive started (MPI_Imrecv); 1 with *info and out (its contents
 * replaced) filled when one has completed, 0 when none has yet. A message
 * whose transfer is under way (a large one from a sender that is slow or
 * stopped) stays in flight for a later call, while other senders' messages
 * come through; each sender's arrive in the order it sent them. */
int mpil_poll_recv(int source, int tag, mpil_info *info, wire_buf *out, ct_error *err);

/* mpil_poll_recv until a message has come (1) or timeout_s has passed (0),
 * completing sends and napping 200 us between looks: never blocks on a
 * sender that stopped. */
int mpil_recv_wait(int source, int tag, double timeout_s, mpil_info *info, wire_buf *out, ct_error *err);

/* Broadcasts buf from root to every rank, MPIL_BCAST_CHUNK bytes at a time:
 * on root buf holds the bytes, elsewhere it receives them (length included). */
int mpil_bcast(int root, wire_buf *buf, ct_error *err);

/* Broadcasts a 64-bit value from root. */
int mpil_bcast_u64(int root, uint64_t *v, ct_error *err);

/* Every rank passes its value; every rank gets the largest (a collective
 * status check: one failing rank lets all leave in order). Waits napping
 * (up to 1 ms between looks), not spinning: ranks wait here for as long as
 * the master's start-up takes. */
int mpil_allreduce_max(int *v, ct_error *err);

#endif
