/* Test shim (built by the pytest suite into a shared library, used via ctypes). */
#include "guard_proto.h"

static gp_parser_t shim_parser;

/* Encode a message from flat values; returns wire length or 0. */
size_t shim_encode(uint8_t id, uint16_t seq, const int64_t *vals, unsigned n_joints,
                   uint8_t *out)
{
    uint8_t payload[GP_MAX_PAYLOAD];
    int len = gp_flat_pack(id, vals, n_joints, payload);
    if (len < 0)
        return 0;
    return gp_encode_frame(id, seq, payload, (size_t)len, out);
}

void shim_reset(void) { gp_parser_init(&shim_parser); }

/* Feed bytes; for each frame write id, seq, n_joints, n_vals, vals... (int64) to rec,
   at most max_frames records of rec_stride int64 each. Returns frames written. */
size_t shim_feed(const uint8_t *data, size_t len, int64_t *rec, size_t rec_stride,
                 size_t max_frames)
{
    size_t i, nf = 0;
    gp_frame_t f;
    for (i = 0; i < len; ++i) {
        if (gp_parser_feed(&shim_parser, data[i], &f) && nf < max_frames) {
            int64_t *r = rec + nf * rec_stride;
            unsigned nj;
            int nv = gp_flat_unpack(f.msg_id, f.payload, f.payload_len, r + 4, &nj);
            r[0] = f.msg_id;
            r[1] = f.seq;
            r[2] = nj;
            r[3] = nv;
            nf++;
        }
    }
    return nf;
}

void shim_stats(uint32_t *out)
{
    const gp_stats_t *s = &shim_parser.stats;
    out[0] = s->bytes;
    out[1] = s->frames;
    out[2] = s->overflows;
    out[3] = s->cobs_errors;
    out[4] = s->short_frames;
    out[5] = s->crc_errors;
    out[6] = s->bad_version;
    out[7] = s->unknown_id;
    out[8] = s->bad_length;
    out[9] = s->seq_gaps;
    out[10] = s->seq_backwards;
}
