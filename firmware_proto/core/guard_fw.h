/* guard_fw: portable C99 firmware core of the guard robot (protocol, modes, setpoint
 * buffer, watchdog, e-stop, joint limits, fixed-point PID), on top of the guard_proto codec.
 *
 * The core follows the state machine and timing rules of firmware_proto/README.md and is
 * bit-for-bit equal to the Python emulator (guardid/firmware/emulator.py, pid.py).
 * No dynamic allocation, no floating point; builds with
 *   cc -std=c99 -Wall -Wextra -Werror -pedantic -I firmware_proto -I firmware_proto/core
 *
 * Porting: fill a gf_hal_t with the board's functions, a gf_config_t with the robot's
 * constants, call gf_init() once, then
 *   - gf_receive_byte() for every byte the UART received (main loop, not the RX interrupt),
 *   - gf_tick() once per tick period (15 ms), after the tick interrupt latched the encoder
 *     counts and the ADC means of the period that just ended,
 *   - gf_estop() from a hardware e-stop input (also cut the PWM in the interrupt itself).
 * The core calls back into the HAL for the sensor values of the tick, the motor outputs and
 * the UART transmit.
 */
#ifndef GUARD_FW_H
#define GUARD_FW_H

#include <stddef.h>
#include <stdint.h>

#include "guard_proto.h"

/* Joints the core has room for (<= GP_MAX_JOINTS); a 2-joint port may define 2 to save RAM. */
#ifndef GF_MAX_JOINTS
#define GF_MAX_JOINTS GP_MAX_JOINTS
#endif
#if GF_MAX_JOINTS < 1 || GF_MAX_JOINTS > 4
#error "GF_MAX_JOINTS must be 1..4"
#endif

#define GF_SETPOINT_DEPTH 8u       /* INFO setpoint_depth */
#define GF_DEFAULT_WATCHDOG_MS 250u
#define GF_Q 16                    /* fractional bits of the PID gains and integral */

/* Hardware abstraction. ctx is passed back to every call. */
typedef struct {
    void *ctx;
    /* Encoder counts of `joint` latched at the tick that just happened. */
    int32_t (*read_counts)(void *ctx, uint8_t joint);
    /* Means over the period that just ended (ADC oversampling): motor voltage [mV] and
       current [mA]. */
    void (*read_adc)(void *ctx, uint8_t joint, int32_t *mv, int32_t *ma);
    /* Drive `joint`: mv is the PWM-quantised voltage [mV] (sign = direction), duty its
       magnitude in PWM steps (0 .. 2^pwm_bits - 1). Called at every tick and at once on
       e-stop / idle. */
    void (*set_output)(void *ctx, uint8_t joint, int32_t mv, uint16_t duty);
    /* Queue bytes for the UART transmitter (one whole frame per call). */
    void (*uart_write)(void *ctx, const uint8_t *data, size_t len);
} gf_hal_t;

typedef struct {
    uint32_t counts_per_rev; /* encoder counts per joint revolution (INFO), >= 1 */
    int32_t supply_mv;       /* PWM supply = output saturation [mV], 1 .. 32767 */
    uint8_t pwm_bits;        /* PWM resolution, 1 .. 16 */
    uint8_t has_limits;      /* position limits below are in force */
    int32_t limit_lo, limit_hi; /* [counts]: no driving below lo / above hi */
    int32_t kp_uv, ki_uv, kd_uv; /* default gains [uV/rad], [uV/(rad s)], [uV s/rad] */
} gf_joint_config_t;

typedef struct {
    uint8_t n_joints;        /* 1 .. GF_MAX_JOINTS */
    uint8_t info_at_reset;   /* send INFO from gf_init (hardware: 1; the emulators: 0) */
    uint32_t tick_us;        /* tick period [us], >= 1 */
    uint32_t firmware_id;    /* INFO firmware_id */
    gf_joint_config_t joint[GF_MAX_JOINTS];
} gf_config_t;

/* One joint's fixed-point PID (see gf_pid_step). */
typedef struct {
    int64_t kp, ki, kd;   /* Q16 gains in mV per count (per tick for ki, times ticks for kd) */
    int64_t prev_error;   /* counts */
    int32_t integral;     /* Q16 mV, |integral| <= limit_mv << 16 */
    int32_t limit_mv;
    uint8_t saturated;
} gf_pid_t;

typedef struct {
    uint32_t tick;
    uint8_t hold;
    int32_t position[GF_MAX_JOINTS];
    int16_t feedforward_mv[GF_MAX_JOINTS]; /* SETPOINT_FF; 0 for SETPOINT */
} gf_setpoint_entry_t;

typedef struct {
    gf_config_t cfg;
    gf_hal_t hal;
    gp_parser_t parser;
    gf_pid_t pid[GF_MAX_JOINTS];
    gf_setpoint_entry_t queue[GF_SETPOINT_DEPTH];
    int32_t setpoint[GF_MAX_JOINTS];
    int16_t feedforward_mv[GF_MAX_JOINTS]; /* added to the PID output, before its limit */
    int32_t counts[GF_MAX_JOINTS];
    int32_t voltage_cmd_mv[GF_MAX_JOINTS];
    int32_t applied_mv[GF_MAX_JOINTS];
    int32_t adc_mv[GF_MAX_JOINTS];
    int32_t adc_ma[GF_MAX_JOINTS];
    uint32_t tick;
    uint32_t last_host_tick;
    uint16_t watchdog_ms;
    uint16_t status;
    uint16_t tx_seq;
    uint8_t q_head, q_len;
    uint8_t mode;
    uint8_t streaming;
    uint8_t decimation;
    uint8_t estop;
    uint8_t watchdog_tripped;
    uint8_t setpoint_hold;
    /* The previous host frame (id, seq, CRC) and its answer: an identical frame that follows
       it (the host retrying a command whose ACK was lost) gets the same ACK/NAK again and is
       not applied again. */
    uint32_t last_crc;
    uint16_t last_seq;
    uint8_t last_id;
    uint8_t have_last;
    uint8_t last_reply; /* GF_REPLY_* */
    uint8_t last_error; /* NAK error code when last_reply is GF_REPLY_NAK */
} gf_fw_t;

/* gf_fw_t.last_reply */
#define GF_REPLY_NONE 0u
#define GF_REPLY_ACK 1u
#define GF_REPLY_NAK 2u

/* Errors of gf_init. */
#define GF_OK 0
#define GF_EBADCONFIG (-1)

/* Reset state, default gains; sends INFO if cfg->info_at_reset. The config is copied. */
int gf_init(gf_fw_t *fw, const gf_config_t *cfg, const gf_hal_t *hal);
/* One byte from the host; a completed valid frame is handled at once (replies are sent
   through hal.uart_write). */
void gf_receive_byte(gf_fw_t *fw, uint8_t byte);
/* The tick: read sensors, watchdog, setpoint, control law, limits, PWM, telemetry. */
void gf_tick(gf_fw_t *fw);
/* Hardware e-stop input: latch, motors 0 V at once, mode IDLE, FAULT estop. */
void gf_estop(gf_fw_t *fw);
/* Time matters (streaming or a moving mode). */
int gf_wants_time(const gf_fw_t *fw);

/* Fixed-point helpers, exported for the tests (equal to guardid/firmware/pid.py). */
/* Q16 gains from micro-unit gains; integers only, exact for every int32 gain, cpr >= 1 and
   tick_us >= 1 (128-bit intermediates). out[3] = kp, ki, kd. */
void gf_pid_gains_q16(int32_t kp_uv, int32_t ki_uv, int32_t kd_uv, uint32_t counts_per_rev,
                      uint32_t tick_us, int64_t out[3]);
void gf_pid_reset(gf_pid_t *pid);
/* One PID step plus the feedforward [mV] (|ff| <= 32767): output [mV] clamped to
   +-limit_mv; sets pid->saturated. */
int32_t gf_pid_step(gf_pid_t *pid, int32_t setpoint, int32_t position, int32_t ff_mv);
/* PWM quantisation: the voltage [mV] of the duty nearest to mv; *duty = its magnitude. */
int32_t gf_pwm_quantise(int32_t mv, int32_t supply_mv, uint8_t pwm_bits, uint16_t *duty);

#endif /* GUARD_FW_H */
