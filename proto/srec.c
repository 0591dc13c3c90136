/* srec.c: sample recordings (srec.h). */
#include "proto/srec.h"

#include <stdlib.h>
#include <string.h>

#include "common/fsutil.h"
#include "proto/wire_mpi.h"

static const char MAGIC[8] = {'C', 'T', 'S', 'R', 'E', 'C', '1', '\n'};

/* Largest recording read (16 M samples of 76 bytes, with headers). */
#define SREC_MAX_BYTES ((size_t)1 << 31)

int srec_write(const char *path, const ct_sample *s, size_t n, ct_error *err)
{
    wire_buf all = {0}, msg = {0};
    int rc = wire_buf_append(&all, MAGIC, sizeof MAGIC, err);
    for (size_t i = 0; !rc && i < n; i += WIRE_MPI_MAX_BATCH) {
        uint32_t k = n - i < WIRE_MPI_MAX_BATCH ? (uint32_t)(n - i) : WIRE_MPI_MAX_BATCH;
        wire_mpi_samples h = {.batch = i / WIRE_MPI_MAX_BATCH, .rank = 0};
        msg.len = 0;
        rc = wire_mpi_encode_samples(&h, s + i, k, &msg, err);
        uint8_t len[4] = {(uint8_t)msg.len, (uint8_t)(msg.len >> 8), (uint8_t)(msg.len >> 16), (uint8_t)(msg.len >> 24)};
        if (!rc) rc = wire_buf_append(&all, len, sizeof len, err);
        if (!rc) rc = wire_buf_append(&all, msg.data, msg.len, err);
    }
    if (!rc) rc = fs_write_atomic(path, all.data, all.len, err);
    wire_buf_free(&all);
    wire_buf_free(&msg);
    return rc;
}

int srec_read(const char *path, ct_sample **out, size_t *n, ct_error *err)
{
    *out = NULL;
    *n = 0;
    char *data = NULL;
    size_t len = 0;
    int rc = fs_read_all(path, SREC_MAX_BYTES, &data, &len, err);
    if (rc) return rc;
    if (len < sizeof MAGIC || memcmp(data, MAGIC, sizeof MAGIC) != 0) {
        free(data);
        return ct_fail(err, CT_EPARSE, "%s: not a sample recording (no CTSREC1 header)", path);
    }
    /* at most one sample per WIRE_MPI_SAMPLE_SIZE bytes */
    size_t cap = len / WIRE_MPI_SAMPLE_SIZE + 1, count = 0;
    ct_sample *s = malloc(cap * sizeof *s);
    if (!s) {
        free(data);
        return ct_fail(err, CT_ENOMEM, "%s: out of memory for %zu samples", path, cap);
    }
    const uint8_t *p = (const uint8_t *)data;
    size_t at = sizeof MAGIC;
    char peer[300];
    snprintf(peer, sizeof peer, "%s", path);
    while (!rc && at < len) {
        if (len - at < 4) {
            rc = ct_fail(err, CT_EPARSE, "%s: truncated block length at offset %zu", path, at);
            break;
        }
        size_t bl = (size_t)p[at] | (size_t)p[at + 1] << 8 | (size_t)p[at + 2] << 16 | (size_t)p[at + 3] << 24;
        at += 4;
        if (bl > len - at) {
            rc = ct_fail(err, CT_EPARSE, "%s: block of %zu bytes at offset %zu passes the end", path, bl, at);
            break;
        }
        wire_mpi_samples h;
        uint32_t got = 0;
        rc = wire_mpi_decode_samples(p + at, bl, peer, &h, s + count, (uint32_t)(cap - count > WIRE_MPI_MAX_BATCH
                                                                                    ? WIRE_MPI_MAX_BATCH
                                                                                    : cap - count),
                                     &got, err);
        count += got;
        at += bl;
    }
    free(data);
    if (rc) {
        free(s);
        return rc;
    }
    *out = s;
    *n = count;
    return CT_OK;
}
