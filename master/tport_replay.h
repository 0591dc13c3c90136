/* tport_replay.h: a tracer port (proto/tport.h) that answers requests from
 * recorded samples (proto/srec.h) at once, by request id: the run that
 * recorded them hands out the same requests again when the session is
 * driven the same way (same scene, view, options and rounds), because its
 * choices depend only on the samples. The saturation benchmark feeds the
 * master this way as fast as it takes samples. A request the recording does
 * not hold, or holds for another image position, is an error. */
#ifndef CT_MASTER_TPORT_REPLAY_H
#define CT_MASTER_TPORT_REPLAY_H

#include <stddef.h>

#include "common/records.h"
#include "proto/tport.h"

/* A port of `lanes` lanes over n recorded samples (copied). */
int tport_replay_new(const ct_sample *rec, size_t n, int lanes, tport **out, ct_error *err);

#endif
