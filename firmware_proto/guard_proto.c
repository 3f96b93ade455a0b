/* guard_proto.c: see guard_proto.h. C99, no malloc, no floating point. */
#include "guard_proto.h"

uint32_t gp_crc32(const uint8_t *data, size_t len)
{
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    unsigned b;
    for (i = 0; i < len; ++i) {
        crc ^= data[i];
        for (b = 0; b < 8u; ++b)
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}

size_t gp_cobs_encode(const uint8_t *in, size_t len, uint8_t *out)
{
    size_t code_at = 0, o = 1, i;
    uint8_t code = 1;
    for (i = 0; i < len; ++i) {
        if (in[i] == 0u) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = in[i];
            if (++code == 0xFFu) {
                out[code_at] = code;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    return o;
}

int gp_cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t *out_len)
{
    size_t i = 0, o = 0, k;
    while (i < len) {
        uint8_t code = in[i++];
        if (code == 0u || (size_t)(code - 1u) > len - i)
            return -1;
        for (k = 1; k < code; ++k) {
            if (in[i] == 0u)
                return -1;
            out[o++] = in[i++];
        }
        if (code != 0xFFu && i < len)
            out[o++] = 0u;
    }
    *out_len = o;
    return 0;
}

size_t gp_encode_frame(uint8_t msg_id, uint16_t seq, const uint8_t *payload, size_t len,
                       uint8_t *out)
{
    uint8_t raw[GP_MAX_RAW];
    size_t i, n;
    uint32_t crc;
    if (len > GP_MAX_PAYLOAD)
        return 0;
    raw[0] = (uint8_t)GP_FRAME_VERSION;
    raw[1] = msg_id;
    gp_put_u16(raw + 2, seq);
    for (i = 0; i < len; ++i)
        raw[GP_HEADER_LEN + i] = payload[i];
    crc = gp_crc32(raw, GP_HEADER_LEN + len);
    gp_put_u32(raw + GP_HEADER_LEN + len, crc);
    n = gp_cobs_encode(raw, GP_MIN_RAW + len, out);
    out[n] = 0u;
    return n + 1u;
}

void gp_parser_init(gp_parser_t *p)
{
    size_t i;
    uint8_t *b = (uint8_t *)p;
    for (i = 0; i < sizeof *p; ++i)
        b[i] = 0u;
}

/* Check one complete segment; 1 and *out filled if it is a valid frame. */
static int gp_segment(gp_parser_t *p, gp_frame_t *out)
{
    gp_stats_t *st = &p->stats;
    size_t n, fixed, pj, plen;
    uint16_t seq;
    unsigned d;
    if (gp_cobs_decode(p->buf, p->len, p->raw, &n) != 0) {
        st->cobs_errors++;
        return 0;
    }
    if (n < GP_MIN_RAW) {
        st->short_frames++;
        return 0;
    }
    if (gp_crc32(p->raw, n - GP_CRC_LEN) != gp_get_u32(p->raw + n - GP_CRC_LEN)) {
        st->crc_errors++;
        return 0;
    }
    if (p->raw[0] != GP_FRAME_VERSION) {
        st->bad_version++;
        return 0;
    }
    if (gp_payload_layout(p->raw[1], &fixed, &pj) != 0) {
        st->unknown_id++;
        return 0;
    }
    plen = n - GP_MIN_RAW;
    if (pj == 0u ? plen != fixed
                 : (plen < fixed + pj || (plen - fixed) % pj != 0u ||
                    (plen - fixed) / pj > GP_MAX_JOINTS)) {
        st->bad_length++;
        return 0;
    }
    seq = (uint16_t)gp_get_u16(p->raw + 2);
    d = p->raw[1] >> 7;
    if (p->have_seq[d] && seq != p->expect_seq[d]) {
        uint16_t gap = (uint16_t)(seq - p->expect_seq[d]);
        if (gap < 0x8000u)
            st->seq_gaps += gap;
        else
            st->seq_backwards++;
    }
    p->have_seq[d] = 1u;
    p->expect_seq[d] = (uint16_t)(seq + 1u);
    st->frames++;
    out->msg_id = p->raw[1];
    out->seq = seq;
    out->payload = p->raw + GP_HEADER_LEN;
    out->payload_len = plen;
    return 1;
}

int gp_parser_feed(gp_parser_t *p, uint8_t byte, gp_frame_t *out)
{
    p->stats.bytes++;
    if (byte == 0u) {
        int ok = 0;
        if (!p->discarding && p->len > 0u)
            ok = gp_segment(p, out);
        p->len = 0;
        p->discarding = 0;
        return ok;
    }
    if (p->discarding)
        return 0;
    if (p->len == GP_MAX_ENCODED) {
        p->stats.overflows++;
        p->discarding = 1u;
        p->len = 0;
        return 0;
    }
    p->buf[p->len++] = byte;
    return 0;
}
