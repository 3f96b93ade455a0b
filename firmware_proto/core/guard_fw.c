/* guard_fw.c: see guard_fw.h. C99, no malloc, no floating point. */
#include "guard_fw.h"

/* ------------------------------------------------------------------ 128-bit integers */
/* Little-endian 32-bit limbs; unsigned, or two's complement where noted. Only the gain
   computation (once per SET_PID) and PID steps with huge gains or errors use them. */
typedef struct {
    uint32_t w[4];
} gf_u128_t;

static void u128_set(gf_u128_t *a, uint64_t v)
{
    a->w[0] = (uint32_t)v;
    a->w[1] = (uint32_t)(v >> 32);
    a->w[2] = 0u;
    a->w[3] = 0u;
}

static void u128_mul_u32(gf_u128_t *a, uint32_t m)
{
    uint64_t carry = 0u;
    unsigned i;
    for (i = 0; i < 4u; ++i) {
        uint64_t t = (uint64_t)a->w[i] * m + carry;
        a->w[i] = (uint32_t)t;
        carry = t >> 32;
    }
}

/* a += v << (32 * limb) (mod 2^128) */
static void u128_add_u64_at(gf_u128_t *a, uint64_t v, unsigned limb)
{
    uint64_t carry = 0u;
    unsigned i;
    for (i = limb; i < 4u; ++i) {
        uint64_t add = (i == limb) ? (v & 0xFFFFFFFFu) : (i == limb + 1u) ? (v >> 32) : 0u;
        uint64_t t = (uint64_t)a->w[i] + add + carry;
        a->w[i] = (uint32_t)t;
        carry = t >> 32;
    }
}

static void u128_mul_u64(gf_u128_t *a, uint64_t m)
{
    gf_u128_t hi = *a;
    unsigned i;
    u128_mul_u32(a, (uint32_t)m);
    u128_mul_u32(&hi, (uint32_t)(m >> 32));
    for (i = 0; i < 3u; ++i) /* a += hi << 32 */
        u128_add_u64_at(a, hi.w[i], i + 1u);
}

static void u128_add(gf_u128_t *a, const gf_u128_t *b)
{
    uint64_t carry = 0u;
    unsigned i;
    for (i = 0; i < 4u; ++i) {
        uint64_t t = (uint64_t)a->w[i] + b->w[i] + carry;
        a->w[i] = (uint32_t)t;
        carry = t >> 32;
    }
}

static void u128_sub(gf_u128_t *a, const gf_u128_t *b)
{
    uint32_t borrow = 0u;
    unsigned i;
    for (i = 0; i < 4u; ++i) {
        uint32_t x = a->w[i], y = b->w[i];
        a->w[i] = x - y - borrow;
        borrow = (x < y || (x == y && borrow)) ? 1u : 0u;
    }
}

static int u128_ge(const gf_u128_t *a, const gf_u128_t *b)
{
    int i;
    for (i = 3; i >= 0; --i)
        if (a->w[i] != b->w[i])
            return a->w[i] > b->w[i];
    return 1;
}

static void u128_shl(gf_u128_t *a, unsigned s) /* s < 32 */
{
    int i;
    if (s == 0u)
        return;
    for (i = 3; i > 0; --i)
        a->w[i] = (a->w[i] << s) | (a->w[i - 1] >> (32u - s));
    a->w[0] <<= s;
}

static void u128_shr1(gf_u128_t *a)
{
    unsigned i;
    for (i = 0; i < 3u; ++i)
        a->w[i] = (a->w[i] >> 1) | (a->w[i + 1] << 31);
    a->w[3] >>= 1;
}

static void u128_neg(gf_u128_t *a)
{
    gf_u128_t one;
    unsigned i;
    for (i = 0; i < 4u; ++i)
        a->w[i] = ~a->w[i];
    u128_set(&one, 1u);
    u128_add(a, &one);
}

/* Number of significant bits of a (0 for a = 0). Constant shifts only: an 8-bit MCU
   shifts by a variable amount one bit at a time. */
static int u128_bits(const gf_u128_t *a)
{
    int w, n;
    for (w = 3; w >= 0; --w) {
        uint32_t x = a->w[w];
        if (x != 0u) {
            for (n = 32 * w; x != 0u; x >>= 1)
                ++n;
            return n;
        }
    }
    return 0;
}

static void u128_shl1(gf_u128_t *a)
{
    a->w[3] = (a->w[3] << 1) | (a->w[2] >> 31);
    a->w[2] = (a->w[2] << 1) | (a->w[1] >> 31);
    a->w[1] = (a->w[1] << 1) | (a->w[0] >> 31);
    a->w[0] <<= 1;
}

/* floor(num / den), den != 0; restoring division, one bit at a time. The remainder starts
   as num's top bits short of den's length (no quotient bit above them can be set), so the
   loop runs once per possible quotient bit, not 128 times, with constant shifts only: an
   8-bit MCU computes SET_PID's gains in its main loop, ahead of the tick's work. */
static void u128_div(const gf_u128_t *num, const gf_u128_t *den, gf_u128_t *q)
{
    gf_u128_t r = *num;
    int skip = u128_bits(num) - u128_bits(den) + 1, k, w;
    uint32_t mask;
    u128_set(q, 0u);
    if (skip <= 0)
        return; /* num < den */
    for (k = 0; k < skip; ++k) /* r = num >> skip: below den */
        u128_shr1(&r);
    w = (skip - 1) / 32;
    mask = (uint32_t)1u << ((skip - 1) % 32);
    for (k = skip; k > 0; --k) { /* bit 32 w + log2(mask) of num, then of q */
        u128_shl1(&r);
        if (num->w[w] & mask)
            r.w[0] |= 1u;
        if (u128_ge(&r, den)) {
            u128_sub(&r, den);
            q->w[w] |= mask;
        }
        mask >>= 1;
        if (mask == 0u) {
            mask = 0x80000000u;
            --w;
        }
    }
}

/* Two's complement product of two int64. */
static void s128_mul(int64_t a, int64_t b, gf_u128_t *r)
{
    uint64_t ma = a < 0 ? (uint64_t)0 - (uint64_t)a : (uint64_t)a;
    uint64_t mb = b < 0 ? (uint64_t)0 - (uint64_t)b : (uint64_t)b;
    uint64_t a0 = ma & 0xFFFFFFFFu, a1 = ma >> 32, b0 = mb & 0xFFFFFFFFu, b1 = mb >> 32;
    u128_set(r, a0 * b0);
    u128_add_u64_at(r, a0 * b1, 1u);
    u128_add_u64_at(r, a1 * b0, 1u);
    u128_add_u64_at(r, a1 * b1, 2u);
    if ((a < 0) != (b < 0))
        u128_neg(r);
}

static void s128_add_i64(gf_u128_t *a, int64_t v)
{
    gf_u128_t b;
    u128_set(&b, (uint64_t)v);
    if (v < 0)
        b.w[2] = b.w[3] = 0xFFFFFFFFu;
    u128_add(a, &b);
}

/* The two's complement value a clamped to [-bound, bound] (bound > 0). */
static int64_t s128_clamp(const gf_u128_t *a, int64_t bound)
{
    gf_u128_t m = *a;
    int neg = (int)(a->w[3] >> 31);
    uint64_t mag;
    if (neg)
        u128_neg(&m);
    mag = ((uint64_t)m.w[1] << 32) | m.w[0];
    if (m.w[3] != 0u || m.w[2] != 0u || mag > (uint64_t)bound)
        return neg ? -bound : bound;
    return neg ? -(int64_t)mag : (int64_t)mag;
}

/* ------------------------------------------------------------------ fixed point */
#define GF_TWO_PI_E9 6283185307u /* 2*pi * 1e9 */

/* round(sign * mag * mul1 * mul2 << 16 / (cpr * 1e12 * div2)), half away from zero. */
static int64_t gain_q16(int32_t g, uint64_t mul2, uint32_t cpr, uint32_t div2)
{
    gf_u128_t num, den, q;
    uint32_t mag = g < 0 ? (uint32_t)0 - (uint32_t)g : (uint32_t)g;
    u128_set(&num, mag);
    u128_mul_u64(&num, GF_TWO_PI_E9);
    u128_mul_u64(&num, mul2);
    u128_shl(&num, GF_Q);
    u128_set(&den, cpr);
    u128_mul_u32(&den, 1000000u);
    u128_mul_u32(&den, 1000000u);
    u128_mul_u32(&den, div2);
    q = den;
    u128_shr1(&q);
    u128_add(&num, &q);
    u128_div(&num, &den, &q);
    /* |q| < 2^63 for every int32 gain, cpr >= 1, tick_us >= 1 */
    return g < 0 ? -(int64_t)(((uint64_t)q.w[1] << 32) | q.w[0])
                 : (int64_t)(((uint64_t)q.w[1] << 32) | q.w[0]);
}

void gf_pid_gains_q16(int32_t kp_uv, int32_t ki_uv, int32_t kd_uv, uint32_t counts_per_rev,
                      uint32_t tick_us, int64_t out[3])
{
    out[0] = gain_q16(kp_uv, 1u, counts_per_rev, 1u);
    out[1] = gain_q16(ki_uv, tick_us, counts_per_rev, 1000000u);
    out[2] = gain_q16(kd_uv, 1000000u, counts_per_rev, tick_us);
}

void gf_pid_reset(gf_pid_t *pid)
{
    pid->integral = 0;
    pid->prev_error = 0;
    pid->saturated = 0u;
}

static int fits31(int64_t v) { return v >= -(int64_t)0x80000000 && v <= (int64_t)0x7FFFFFFF; }

int32_t gf_pid_step(gf_pid_t *pid, int32_t setpoint, int32_t position, int32_t ff_mv)
{
    int64_t ff_q = (int64_t)ff_mv * ((int64_t)1 << GF_Q); /* feedforward, Q16 mV */
    int64_t error = (int64_t)setpoint - position;
    int64_t derr = error - pid->prev_error;
    int64_t lim_q = (int64_t)pid->limit_mv << GF_Q;
    int64_t integral, raw, out;
    if (fits31(pid->kp) && fits31(pid->ki) && fits31(pid->kd) && fits31(error) &&
        fits31(derr)) {
        /* every product < 2^62: plain int64 is exact */
        integral = pid->integral + pid->ki * error;
        if (integral > lim_q)
            integral = lim_q;
        else if (integral < -lim_q)
            integral = -lim_q;
        raw = pid->kp * error + integral + pid->kd * derr + ff_q;
    } else {
        /* exact 128-bit sums; |raw| is clamped to 2^62, far beyond any output limit */
        gf_u128_t acc, t;
        s128_mul(pid->ki, error, &acc);
        s128_add_i64(&acc, pid->integral);
        integral = s128_clamp(&acc, lim_q);
        s128_mul(pid->kp, error, &acc);
        s128_mul(pid->kd, derr, &t);
        u128_add(&acc, &t);
        s128_add_i64(&acc, integral);
        s128_add_i64(&acc, ff_q);
        raw = s128_clamp(&acc, (int64_t)1 << 62);
    }
    out = raw >= 0 ? raw >> GF_Q : -((-raw) >> GF_Q);
    pid->saturated = (uint8_t)(out > pid->limit_mv || out < -(int64_t)pid->limit_mv);
    if (pid->saturated)
        out = out > 0 ? pid->limit_mv : -(int64_t)pid->limit_mv;
    /* anti-windup: integrate only while not pushing further into saturation */
    if (!(pid->saturated && (error > 0) == (out > 0)))
        pid->integral = (int32_t)integral;
    pid->prev_error = error;
    return (int32_t)out;
}

int32_t gf_pwm_quantise(int32_t mv, int32_t supply_mv, uint8_t pwm_bits, uint16_t *duty)
{
    uint32_t levels = ((uint32_t)1u << pwm_bits) - 1u;
    uint32_t supply = (uint32_t)supply_mv;
    uint32_t mag = mv < 0 ? (uint32_t)0 - (uint32_t)mv : (uint32_t)mv;
    uint32_t d, duty_mv;
    if (mag > supply) /* callers clamp first; never drive beyond the supply */
        mag = supply;
    d = (mag * levels + supply / 2u) / supply;
    duty_mv = (d * supply + levels / 2u) / levels;
    *duty = (uint16_t)d;
    return mv >= 0 ? (int32_t)duty_mv : -(int32_t)duty_mv;
}

/* ------------------------------------------------------------------ sending */
static void send(gf_fw_t *fw, uint8_t id, const uint8_t *payload, size_t len)
{
    uint8_t wire[GP_MAX_WIRE];
    size_t n = gp_encode_frame(id, fw->tx_seq, payload, len, wire);
    fw->tx_seq = (uint16_t)(fw->tx_seq + 1u);
    fw->hal.uart_write(fw->hal.ctx, wire, n);
}

static void send_ack(gf_fw_t *fw, const gp_frame_t *f)
{
    gp_ack_t m;
    uint8_t p[GP_ACK_FIXED_SIZE];
    m.ack_seq = f->seq;
    m.ack_id = f->msg_id;
    fw->last_reply = GF_REPLY_ACK;
    send(fw, GP_MSG_ACK, p, gp_pack_ack(&m, p));
}

static void send_nak(gf_fw_t *fw, const gp_frame_t *f, uint8_t error)
{
    gp_nak_t m;
    uint8_t p[GP_NAK_FIXED_SIZE];
    m.ack_seq = f->seq;
    m.ack_id = f->msg_id;
    m.error = error;
    fw->last_reply = GF_REPLY_NAK;
    fw->last_error = error;
    send(fw, GP_MSG_NAK, p, gp_pack_nak(&m, p));
}

static void send_fault(gf_fw_t *fw, uint8_t code, int32_t detail)
{
    gp_fault_t m;
    uint8_t p[GP_FAULT_FIXED_SIZE];
    m.tick = fw->tick;
    m.code = code;
    m.joint = 0xFFu;
    m.detail = detail;
    send(fw, GP_MSG_FAULT, p, gp_pack_fault(&m, p));
}

static void send_info(gf_fw_t *fw)
{
    gp_info_t m;
    uint8_t p[GP_MAX_PAYLOAD];
    unsigned j;
    m.protocol_version = (uint8_t)GP_PROTOCOL_VERSION;
    m.joint_count = fw->cfg.n_joints;
    m.capabilities = (uint16_t)(GP_CAPABILITY_CURRENT_SENSE | GP_CAPABILITY_VOLTAGE_SENSE |
                                GP_CAPABILITY_SETPOINT_BUFFER | GP_CAPABILITY_WATCHDOG |
                                GP_CAPABILITY_VOLTAGE_MODE | GP_CAPABILITY_FEEDFORWARD);
    m.firmware_id = fw->cfg.firmware_id;
    m.tick_period = fw->cfg.tick_us;
    m.watchdog_timeout = fw->watchdog_ms;
    m.setpoint_depth = (uint8_t)GF_SETPOINT_DEPTH;
    m.n_joints = fw->cfg.n_joints;
    for (j = 0; j < fw->cfg.n_joints; ++j)
        m.counts_per_rev[j] = fw->cfg.joint[j].counts_per_rev;
    send(fw, GP_MSG_INFO, p, gp_pack_info(&m, p));
}

static int16_t clamp16(int32_t v)
{
    return (int16_t)(v > 32767 ? 32767 : v < -32768 ? -32768 : v);
}

static void send_telemetry(gf_fw_t *fw)
{
    gp_telemetry_t m;
    uint8_t p[GP_MAX_PAYLOAD];
    unsigned j;
    m.tick = fw->tick;
    m.status = fw->status;
    m.mode = fw->mode;
    m.n_joints = fw->cfg.n_joints;
    for (j = 0; j < fw->cfg.n_joints; ++j) {
        m.position[j] = fw->counts[j];
        m.voltage[j] = clamp16(fw->adc_mv[j]);
        m.current[j] = clamp16(fw->adc_ma[j]);
        m.setpoint[j] = fw->setpoint[j];
    }
    send(fw, GP_MSG_TELEMETRY, p, gp_pack_telemetry(&m, p));
}

/* ------------------------------------------------------------------ state machine */
static void output(gf_fw_t *fw, unsigned j, int32_t mv)
{
    uint16_t duty;
    fw->applied_mv[j] =
        gf_pwm_quantise(mv, fw->cfg.joint[j].supply_mv, fw->cfg.joint[j].pwm_bits, &duty);
    fw->hal.set_output(fw->hal.ctx, (uint8_t)j, fw->applied_mv[j], duty);
}

static void enter_mode(gf_fw_t *fw, uint8_t mode)
{
    unsigned j;
    fw->mode = mode;
    fw->q_len = 0u;
    fw->setpoint_hold = 1u; /* no underrun before the first streamed setpoint */
    for (j = 0; j < fw->cfg.n_joints; ++j) {
        fw->setpoint[j] = fw->counts[j];
        fw->feedforward_mv[j] = 0;
        fw->voltage_cmd_mv[j] = 0;
        gf_pid_reset(&fw->pid[j]);
        if (mode == GP_MODE_IDLE)
            output(fw, j, 0); /* motors 0 V at once */
    }
}

static void latch_estop(gf_fw_t *fw, const gp_frame_t *f)
{
    fw->estop = 1u;
    enter_mode(fw, GP_MODE_IDLE);
    if (f != NULL)
        send_ack(fw, f);
    send_fault(fw, (uint8_t)GP_FAULT_ESTOP, 0);
}

/* Serial tick arithmetic: a - b as a signed distance. */
static int32_t tick_diff(uint32_t a, uint32_t b)
{
    uint32_t d = a - b;
    return d >= 0x80000000u ? -(int32_t)(0xFFFFFFFFu - d) - 1 : (int32_t)d;
}

static void on_set_pid(gf_fw_t *fw, const gp_frame_t *f)
{
    gp_set_pid_t m;
    int64_t g[3];
    gf_pid_t *pid;
    if (gp_unpack_set_pid(f->payload, f->payload_len, &m) != 0)
        return;
    if (m.joint >= fw->cfg.n_joints) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BAD_JOINT);
        return;
    }
    gf_pid_gains_q16(m.kp, m.ki, m.kd, fw->cfg.joint[m.joint].counts_per_rev, fw->cfg.tick_us,
                     g);
    pid = &fw->pid[m.joint];
    pid->kp = g[0];
    pid->ki = g[1];
    pid->kd = g[2];
    send_ack(fw, f);
}

static void on_set_mode(gf_fw_t *fw, const gp_frame_t *f)
{
    uint8_t mode = f->payload[0];
    if (mode > GP_MODE_VOLTAGE) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BAD_VALUE);
        return;
    }
    if (mode != GP_MODE_IDLE && fw->estop) {
        send_nak(fw, f, (uint8_t)GP_ERROR_ESTOP_ACTIVE);
        return;
    }
    if (mode != fw->mode)
        enter_mode(fw, mode);
    if (mode != GP_MODE_IDLE)
        fw->watchdog_tripped = 0u;
    send_ack(fw, f);
}

/* Queue a SETPOINT (feedforward NULL: 0 V) or SETPOINT_FF, or NAK it. */
static void queue_setpoint(gf_fw_t *fw, const gp_frame_t *f, const gp_setpoint_t *m,
                           const int16_t *feedforward)
{
    gf_setpoint_entry_t *e;
    unsigned j;
    uint8_t ff_ok = 1u;
    if (feedforward != NULL)
        for (j = 0; j < m->n_joints && j < fw->cfg.n_joints; ++j)
            if (feedforward[j] > fw->cfg.joint[j].supply_mv ||
                feedforward[j] < -fw->cfg.joint[j].supply_mv)
                ff_ok = 0u;
    if (m->n_joints != fw->cfg.n_joints) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BAD_JOINT);
    } else if (fw->estop) {
        send_nak(fw, f, (uint8_t)GP_ERROR_ESTOP_ACTIVE);
    } else if (fw->mode != GP_MODE_POSITION) {
        send_nak(fw, f, (uint8_t)GP_ERROR_WRONG_MODE);
    } else if (tick_diff(m->tick, fw->tick) <= 0) {
        send_nak(fw, f, (uint8_t)GP_ERROR_SETPOINT_LATE);
    } else if (fw->q_len > 0u &&
               tick_diff(m->tick, fw->queue[(fw->q_head + fw->q_len - 1u) % GF_SETPOINT_DEPTH]
                                     .tick) <= 0) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BAD_VALUE);
    } else if (fw->q_len >= GF_SETPOINT_DEPTH) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BUFFER_FULL);
    } else if (!ff_ok) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BAD_VALUE);
    } else {
        e = &fw->queue[(fw->q_head + fw->q_len) % GF_SETPOINT_DEPTH];
        e->tick = m->tick;
        e->hold = (uint8_t)((m->flags & GP_SETPOINT_FLAGS_HOLD) != 0u);
        for (j = 0; j < fw->cfg.n_joints; ++j) {
            e->position[j] = m->position[j];
            e->feedforward_mv[j] = feedforward != NULL ? feedforward[j] : (int16_t)0;
        }
        fw->q_len++;
    }
}

static void on_setpoint(gf_fw_t *fw, const gp_frame_t *f)
{
    gp_setpoint_t m;
    if (gp_unpack_setpoint(f->payload, f->payload_len, &m) == 0)
        queue_setpoint(fw, f, &m, NULL);
}

static void on_setpoint_ff(gf_fw_t *fw, const gp_frame_t *f)
{
    gp_setpoint_ff_t m;
    gp_setpoint_t sp;
    unsigned j;
    if (gp_unpack_setpoint_ff(f->payload, f->payload_len, &m) != 0)
        return;
    sp.tick = m.tick;
    sp.flags = m.flags;
    sp.n_joints = m.n_joints;
    for (j = 0; j < m.n_joints; ++j)
        sp.position[j] = m.position[j];
    queue_setpoint(fw, f, &sp, m.feedforward);
}

static void on_set_voltage(gf_fw_t *fw, const gp_frame_t *f)
{
    gp_set_voltage_t m;
    unsigned j;
    if (gp_unpack_set_voltage(f->payload, f->payload_len, &m) != 0)
        return;
    if (m.n_joints != fw->cfg.n_joints) {
        send_nak(fw, f, (uint8_t)GP_ERROR_BAD_JOINT);
        return;
    }
    if (fw->estop) {
        send_nak(fw, f, (uint8_t)GP_ERROR_ESTOP_ACTIVE);
        return;
    }
    if (fw->mode != GP_MODE_VOLTAGE) {
        send_nak(fw, f, (uint8_t)GP_ERROR_WRONG_MODE);
        return;
    }
    for (j = 0; j < fw->cfg.n_joints; ++j) {
        int32_t v = m.voltage[j];
        if (v > fw->cfg.joint[j].supply_mv || v < -fw->cfg.joint[j].supply_mv) {
            send_nak(fw, f, (uint8_t)GP_ERROR_BAD_VALUE);
            return;
        }
    }
    for (j = 0; j < fw->cfg.n_joints; ++j)
        fw->voltage_cmd_mv[j] = m.voltage[j];
}

/* A repeat of the previous host frame that was answered by ACK/NAK: answer it again. */
static int resend_reply(gf_fw_t *fw, const gp_frame_t *f)
{
    /* the frame's CRC follows its payload in the parser's buffer (header | payload | crc) */
    uint32_t crc = gp_get_u32(f->payload + f->payload_len);
    if (fw->have_last && fw->last_reply != GF_REPLY_NONE && f->msg_id == fw->last_id &&
        f->seq == fw->last_seq && crc == fw->last_crc) {
        if (fw->last_reply == GF_REPLY_ACK)
            send_ack(fw, f);
        else
            send_nak(fw, f, fw->last_error);
        return 1;
    }
    fw->have_last = 1u;
    fw->last_id = f->msg_id;
    fw->last_seq = f->seq;
    fw->last_crc = crc;
    fw->last_reply = GF_REPLY_NONE;
    return 0;
}

static void handle(gf_fw_t *fw, const gp_frame_t *f)
{
    fw->last_host_tick = fw->tick; /* any valid frame feeds the watchdog */
    if (resend_reply(fw, f))
        return;
    switch (f->msg_id) {
    case GP_MSG_HELLO:
        send_info(fw);
        break;
    case GP_MSG_PING: {
        gp_ping_t ping;
        gp_pong_t pong;
        uint8_t p[GP_PONG_FIXED_SIZE];
        if (gp_unpack_ping(f->payload, f->payload_len, &ping) != 0)
            break;
        pong.nonce = ping.nonce;
        pong.tick = fw->tick;
        send(fw, GP_MSG_PONG, p, gp_pack_pong(&pong, p));
        break;
    }
    case GP_MSG_SET_MODE:
        on_set_mode(fw, f);
        break;
    case GP_MSG_SET_PID:
        on_set_pid(fw, f);
        break;
    case GP_MSG_SETPOINT:
        on_setpoint(fw, f);
        break;
    case GP_MSG_SETPOINT_FF:
        on_setpoint_ff(fw, f);
        break;
    case GP_MSG_SET_VOLTAGE:
        on_set_voltage(fw, f);
        break;
    case GP_MSG_START_STREAM:
        if (f->payload[0] < 1u) {
            send_nak(fw, f, (uint8_t)GP_ERROR_BAD_VALUE);
        } else {
            fw->streaming = 1u;
            fw->decimation = f->payload[0];
            send_ack(fw, f);
        }
        break;
    case GP_MSG_STOP_STREAM:
        fw->streaming = 0u;
        send_ack(fw, f);
        break;
    case GP_MSG_ESTOP:
        latch_estop(fw, f);
        break;
    case GP_MSG_CLEAR_ESTOP:
        fw->estop = 0u;
        fw->watchdog_tripped = 0u;
        send_ack(fw, f);
        break;
    case GP_MSG_SET_WATCHDOG: {
        uint16_t timeout = (uint16_t)gp_get_u16(f->payload);
        if (timeout == 0u) {
            send_nak(fw, f, (uint8_t)GP_ERROR_BAD_VALUE);
        } else {
            fw->watchdog_ms = timeout;
            send_ack(fw, f);
        }
        break;
    }
    default: /* MCU->host ids: valid frames, nothing to do */
        break;
    }
}

/* ------------------------------------------------------------------ public */
int gf_init(gf_fw_t *fw, const gf_config_t *cfg, const gf_hal_t *hal)
{
    size_t i;
    unsigned j;
    uint8_t *b = (uint8_t *)fw;
    if (cfg->n_joints < 1u || cfg->n_joints > GF_MAX_JOINTS || cfg->tick_us < 1u)
        return GF_EBADCONFIG;
    for (j = 0; j < cfg->n_joints; ++j) {
        const gf_joint_config_t *jc = &cfg->joint[j];
        if (jc->counts_per_rev < 1u || jc->supply_mv < 1 || jc->supply_mv > 32767 ||
            jc->pwm_bits < 1u || jc->pwm_bits > 16u ||
            (jc->has_limits && jc->limit_lo > jc->limit_hi))
            return GF_EBADCONFIG;
    }
    for (i = 0; i < sizeof *fw; ++i)
        b[i] = 0u;
    fw->cfg = *cfg;
    fw->hal = *hal;
    gp_parser_init(&fw->parser);
    fw->mode = GP_MODE_IDLE;
    fw->decimation = 1u;
    fw->watchdog_ms = (uint16_t)GF_DEFAULT_WATCHDOG_MS;
    fw->setpoint_hold = 1u;
    for (j = 0; j < cfg->n_joints; ++j) {
        const gf_joint_config_t *jc = &cfg->joint[j];
        int64_t g[3];
        fw->pid[j].limit_mv = jc->supply_mv;
        gf_pid_gains_q16(jc->kp_uv, jc->ki_uv, jc->kd_uv, jc->counts_per_rev, cfg->tick_us, g);
        fw->pid[j].kp = g[0];
        fw->pid[j].ki = g[1];
        fw->pid[j].kd = g[2];
        output(fw, j, 0);
    }
    if (cfg->info_at_reset)
        send_info(fw);
    return GF_OK;
}

void gf_receive_byte(gf_fw_t *fw, uint8_t byte)
{
    gp_frame_t f;
    if (gp_parser_feed(&fw->parser, byte, &f))
        handle(fw, &f);
}

void gf_estop(gf_fw_t *fw) { latch_estop(fw, NULL); }

int gf_wants_time(const gf_fw_t *fw) { return fw->streaming || fw->mode != GP_MODE_IDLE; }

void gf_tick(gf_fw_t *fw)
{
    const unsigned n = fw->cfg.n_joints;
    int32_t out[GF_MAX_JOINTS];
    uint16_t status = 0u;
    unsigned j;
    fw->tick++;
    for (j = 0; j < n; ++j) {
        fw->counts[j] = fw->hal.read_counts(fw->hal.ctx, (uint8_t)j);
        fw->hal.read_adc(fw->hal.ctx, (uint8_t)j, &fw->adc_mv[j], &fw->adc_ma[j]);
    }
    if (fw->mode != GP_MODE_IDLE) {
        uint64_t silent_ms = (uint64_t)(fw->tick - fw->last_host_tick) * fw->cfg.tick_us / 1000u;
        if (silent_ms >= fw->watchdog_ms) {
            fw->watchdog_tripped = 1u;
            enter_mode(fw, GP_MODE_IDLE);
            send_fault(fw, (uint8_t)GP_FAULT_WATCHDOG,
                       silent_ms > 0x7FFFFFFFu ? 0x7FFFFFFF : (int32_t)silent_ms);
        }
    }
    if (fw->mode == GP_MODE_POSITION) {
        uint8_t due = 0u;
        while (fw->q_len > 0u && tick_diff(fw->queue[fw->q_head].tick, fw->tick) <= 0) {
            const gf_setpoint_entry_t *e = &fw->queue[fw->q_head];
            for (j = 0; j < n; ++j) {
                fw->setpoint[j] = e->position[j];
                fw->feedforward_mv[j] = e->feedforward_mv[j];
            }
            fw->setpoint_hold = e->hold;
            fw->q_head = (uint8_t)((fw->q_head + 1u) % GF_SETPOINT_DEPTH);
            fw->q_len--;
            due = 1u;
        }
        if (!due && !fw->setpoint_hold)
            status |= GP_STATUS_SETPOINT_UNDERRUN;
        for (j = 0; j < n; ++j) {
            out[j] = gf_pid_step(&fw->pid[j], fw->setpoint[j], fw->counts[j],
                                 fw->feedforward_mv[j]);
            if (fw->pid[j].saturated)
                status |= (uint16_t)(GP_STATUS_SATURATED_J0 << j);
        }
    } else if (fw->mode == GP_MODE_VOLTAGE) {
        for (j = 0; j < n; ++j) {
            int32_t s = fw->cfg.joint[j].supply_mv, v = fw->voltage_cmd_mv[j];
            out[j] = v > s ? s : v < -s ? -s : v;
        }
    } else {
        for (j = 0; j < n; ++j)
            out[j] = 0;
    }
    for (j = 0; j < n; ++j) {
        const gf_joint_config_t *jc = &fw->cfg.joint[j];
        if (jc->has_limits && ((fw->counts[j] >= jc->limit_hi && out[j] > 0) ||
                               (fw->counts[j] <= jc->limit_lo && out[j] < 0))) {
            out[j] = 0;
            status |= (uint16_t)(GP_STATUS_LIMIT_J0 << j);
        }
        output(fw, j, out[j]);
    }
    if (fw->watchdog_tripped)
        status |= GP_STATUS_WATCHDOG_TRIPPED;
    if (fw->estop)
        status |= GP_STATUS_ESTOP;
    fw->status = status;
    if (fw->streaming && fw->tick % fw->decimation == 0u)
        send_telemetry(fw);
}
