/* guard_proto: portable C99 codec of the guard robot wire protocol.
 *
 * Frame on the wire: COBS(version u8 | msg_id u8 | seq u16 | payload | crc32 u32) 0x00
 * (little-endian; CRC-32/ISO-HDLC = zlib.crc32 over header + payload).
 * No dynamic allocation, no floating point. Message structs, ids and pack/unpack
 * functions are in the generated guard_proto_msgs.h (see messages.yaml).
 */
#ifndef GUARD_PROTO_H
#define GUARD_PROTO_H

#include <stddef.h>
#include <stdint.h>

#include "guard_proto_msgs.h"

#define GP_HEADER_LEN 4u
#define GP_CRC_LEN 4u
#define GP_MIN_RAW (GP_HEADER_LEN + GP_CRC_LEN)
#define GP_MAX_RAW (GP_MIN_RAW + GP_MAX_PAYLOAD)
/* Longest COBS-encoded frame without its delimiter; longer segments are overflows. */
#define GP_MAX_ENCODED (GP_MAX_RAW + GP_MAX_RAW / 254u + 1u)
/* Largest output of gp_encode_frame (encoded frame + 0x00 delimiter). */
#define GP_MAX_WIRE (GP_MAX_ENCODED + 1u)

/* CRC-32 (reflected 0xEDB88320, init and final xor 0xFFFFFFFF), as zlib.crc32. */
uint32_t gp_crc32(const uint8_t *data, size_t len);

/* COBS: encode returns the encoded length (<= len + len/254 + 1), never writes 0x00.
   decode returns 0 and sets *out_len, or -1 on invalid input (a 0x00 byte, or a code
   byte pointing past the end); out must hold len bytes. */
size_t gp_cobs_encode(const uint8_t *in, size_t len, uint8_t *out);
int gp_cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t *out_len);

/* Encode one frame into out (GP_MAX_WIRE bytes suffice); returns bytes incl. delimiter,
   0 if len > GP_MAX_PAYLOAD. */
size_t gp_encode_frame(uint8_t msg_id, uint16_t seq, const uint8_t *payload, size_t len,
                       uint8_t *out);

typedef struct {
    uint32_t bytes, frames, overflows, cobs_errors, short_frames, crc_errors;
    uint32_t bad_version, unknown_id, bad_length, seq_gaps, seq_backwards;
} gp_stats_t;

typedef struct {
    uint8_t msg_id;
    uint16_t seq;
    const uint8_t *payload; /* points into the parser; valid until the next feed */
    size_t payload_len;
} gp_frame_t;

typedef struct {
    uint8_t buf[GP_MAX_ENCODED];
    uint8_t raw[GP_MAX_RAW];
    size_t len;
    uint8_t discarding;
    uint8_t have_seq[2];  /* [0] host->mcu, [1] mcu->host */
    uint16_t expect_seq[2];
    gp_stats_t stats;
} gp_parser_t;

void gp_parser_init(gp_parser_t *p);
/* Feed one byte. Returns 1 when it completed a valid frame (then *out is filled), else 0.
   Errors are only counted in p->stats, with the same rules as the Python FrameParser. */
int gp_parser_feed(gp_parser_t *p, uint8_t byte, gp_frame_t *out);

#endif /* GUARD_PROTO_H */
