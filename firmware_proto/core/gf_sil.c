/* gf_sil.c: software-in-the-loop hardware layer for guard_fw, loaded by Python via ctypes
 * (guardid/firmware/c_core.py). Not part of a firmware build.
 *
 * The "hardware" is a struct the host fills before each tick: the encoder counts and the
 * period-mean ADC values of the simulated plant's sample. The motor outputs the core sets
 * and the bytes it transmits are kept for the host to collect. Any number of instances;
 * the host allocates gf_sil_size() bytes (8-byte aligned) per instance.
 */
#include "guard_fw.h"

#define GF_SIL_OUT 4096u
#define GF_SIL_HEADROOM 512u /* receive() stops while less room is left in the output */

typedef struct {
    gf_fw_t fw;
    int32_t counts[GF_MAX_JOINTS];
    int32_t mv[GF_MAX_JOINTS];
    int32_t ma[GF_MAX_JOINTS];
    int32_t out_mv[GF_MAX_JOINTS];
    uint16_t out_duty[GF_MAX_JOINTS];
    size_t out_len;
    uint32_t overflows;
    uint8_t out[GF_SIL_OUT];
} gf_sil_t;

static int32_t sil_read_counts(void *ctx, uint8_t joint)
{
    return ((gf_sil_t *)ctx)->counts[joint];
}

static void sil_read_adc(void *ctx, uint8_t joint, int32_t *mv, int32_t *ma)
{
    gf_sil_t *s = (gf_sil_t *)ctx;
    *mv = s->mv[joint];
    *ma = s->ma[joint];
}

static void sil_set_output(void *ctx, uint8_t joint, int32_t mv, uint16_t duty)
{
    gf_sil_t *s = (gf_sil_t *)ctx;
    s->out_mv[joint] = mv;
    s->out_duty[joint] = duty;
}

static void sil_uart_write(void *ctx, const uint8_t *data, size_t len)
{
    gf_sil_t *s = (gf_sil_t *)ctx;
    size_t i;
    if (len > GF_SIL_OUT - s->out_len) {
        s->overflows++;
        return;
    }
    for (i = 0; i < len; ++i)
        s->out[s->out_len + i] = data[i];
    s->out_len += len;
}

size_t gf_sil_size(void) { return sizeof(gf_sil_t); }

/* Flat configuration: n_joints, info_at_reset, tick_us, firmware_id, then per joint
   counts_per_rev, supply_mv, pwm_bits, has_limits, limit_lo, limit_hi, kp_uv, ki_uv, kd_uv.
   Returns GF_OK or GF_EBADCONFIG. */
int gf_sil_init(gf_sil_t *s, const int64_t *cfg, size_t n_values)
{
    gf_config_t c;
    gf_hal_t hal;
    size_t i;
    unsigned j;
    uint8_t *b = (uint8_t *)s;
    for (i = 0; i < sizeof *s; ++i)
        b[i] = 0u;
    for (i = 0; i < sizeof c; ++i)
        ((uint8_t *)&c)[i] = 0u;
    if (n_values < 4u || cfg[0] < 1 || cfg[0] > (int64_t)GF_MAX_JOINTS ||
        n_values != 4u + 9u * (size_t)cfg[0])
        return GF_EBADCONFIG;
    c.n_joints = (uint8_t)cfg[0];
    c.info_at_reset = (uint8_t)(cfg[1] != 0);
    c.tick_us = (uint32_t)cfg[2];
    c.firmware_id = (uint32_t)cfg[3];
    for (j = 0; j < c.n_joints; ++j) {
        const int64_t *v = cfg + 4u + 9u * j;
        c.joint[j].counts_per_rev = (uint32_t)v[0];
        c.joint[j].supply_mv = (int32_t)v[1];
        c.joint[j].pwm_bits = (uint8_t)v[2];
        c.joint[j].has_limits = (uint8_t)(v[3] != 0);
        c.joint[j].limit_lo = (int32_t)v[4];
        c.joint[j].limit_hi = (int32_t)v[5];
        c.joint[j].kp_uv = (int32_t)v[6];
        c.joint[j].ki_uv = (int32_t)v[7];
        c.joint[j].kd_uv = (int32_t)v[8];
    }
    hal.ctx = s;
    hal.read_counts = sil_read_counts;
    hal.read_adc = sil_read_adc;
    hal.set_output = sil_set_output;
    hal.uart_write = sil_uart_write;
    return gf_init(&s->fw, &c, &hal);
}

/* Feed host bytes; returns how many were consumed (stops early when the output buffer
   needs draining with gf_sil_take). */
size_t gf_sil_receive(gf_sil_t *s, const uint8_t *data, size_t len)
{
    size_t i;
    for (i = 0; i < len && GF_SIL_OUT - s->out_len >= GF_SIL_HEADROOM; ++i)
        gf_receive_byte(&s->fw, data[i]);
    return i;
}

/* The motor voltages [mV] in force now (held over the next period). */
void gf_sil_outputs(const gf_sil_t *s, int32_t *mv)
{
    unsigned j;
    for (j = 0; j < s->fw.cfg.n_joints; ++j)
        mv[j] = s->out_mv[j];
}

/* One tick with the plant's sample: encoder counts, period-mean voltage [mV], current [mA]. */
void gf_sil_tick(gf_sil_t *s, const int32_t *counts, const int32_t *mv, const int32_t *ma)
{
    unsigned j;
    for (j = 0; j < s->fw.cfg.n_joints; ++j) {
        s->counts[j] = counts[j];
        s->mv[j] = mv[j];
        s->ma[j] = ma[j];
    }
    gf_tick(&s->fw);
}

void gf_sil_estop(gf_sil_t *s) { gf_estop(&s->fw); }

/* Copy out (and forget) the transmitted bytes; returns their count (<= cap). */
size_t gf_sil_take(gf_sil_t *s, uint8_t *buf, size_t cap)
{
    size_t n = s->out_len < cap ? s->out_len : cap, i;
    for (i = 0; i < n; ++i)
        buf[i] = s->out[i];
    for (i = n; i < s->out_len; ++i)
        s->out[i - n] = s->out[i];
    s->out_len -= n;
    return n;
}

size_t gf_sil_pending(const gf_sil_t *s) { return s->out_len; }
uint32_t gf_sil_overflows(const gf_sil_t *s) { return s->overflows; }

/* State for the host: tick, mode, status, streaming, estop, watchdog_tripped, wants_time,
   watchdog_ms, queue length, rx frames, rx errors (all parser error counters summed). */
void gf_sil_state(const gf_sil_t *s, int64_t *v)
{
    const gf_fw_t *fw = &s->fw;
    const gp_stats_t *st = &fw->parser.stats;
    v[0] = fw->tick;
    v[1] = fw->mode;
    v[2] = fw->status;
    v[3] = fw->streaming;
    v[4] = fw->estop;
    v[5] = fw->watchdog_tripped;
    v[6] = gf_wants_time(fw);
    v[7] = fw->watchdog_ms;
    v[8] = fw->q_len;
    v[9] = st->frames;
    v[10] = (int64_t)st->overflows + st->cobs_errors + st->short_frames + st->crc_errors +
            st->bad_version + st->unknown_id + st->bad_length;
}

/* Tests: start the tick counter elsewhere (e.g. just before the u32 wrap). */
void gf_sil_set_tick(gf_sil_t *s, uint32_t tick)
{
    s->fw.tick = tick;
    s->fw.last_host_tick = tick;
}

/* Tests: the fixed-point helpers on raw values. pid[] = kp, ki, kd, integral, prev_error,
   limit_mv, saturated (in/out). */
int32_t gf_sil_pid_step(int64_t *pid, int32_t setpoint, int32_t position, int32_t ff_mv)
{
    gf_pid_t p;
    int32_t out;
    p.kp = pid[0];
    p.ki = pid[1];
    p.kd = pid[2];
    p.integral = (int32_t)pid[3];
    p.prev_error = pid[4];
    p.limit_mv = (int32_t)pid[5];
    p.saturated = (uint8_t)pid[6];
    out = gf_pid_step(&p, setpoint, position, ff_mv);
    pid[3] = p.integral;
    pid[4] = p.prev_error;
    pid[6] = p.saturated;
    return out;
}

void gf_sil_gains(int32_t kp, int32_t ki, int32_t kd, uint32_t cpr, uint32_t tick_us,
                  int64_t *out)
{
    gf_pid_gains_q16(kp, ki, kd, cpr, tick_us, out);
}

int32_t gf_sil_pwm(int32_t mv, int32_t supply_mv, uint8_t pwm_bits)
{
    uint16_t duty;
    return gf_pwm_quantise(mv, supply_mv, pwm_bits, &duty);
}
