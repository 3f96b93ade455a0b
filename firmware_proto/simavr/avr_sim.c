/* avr_sim.c: the AVR port's ELF (firmware_proto/avr) in simavr, bound to the simulated
 * plant one tick at a time. Loaded by Python via ctypes (guardid/firmware/avr_sim/), not
 * part of a firmware build. Host C99; simavr (libsimavr-dev) does the MCU.
 *
 * Time: the plant's period k spans AVR cycles [t1_k + L, t1_k + L + P) where t1_k is the
 * cycle Timer1's compare match k is raised, P the tick in cycles and L the output latency
 * (the plant samples the PWM duty and DIR pins L cycles after the tick interrupt and holds
 * them over its period). as_run_tick() takes the plant's motion over one period (position
 * and speed at both ends, in encoder counts and counts/s) and its period-mean current and
 * voltage, schedules the quadrature edges at the cycles the shaft crosses each count
 * (cubic Hermite path between the ends), feeds the ADC conversions through the board's
 * analog front end with noise, paces host bytes into the UART at its baud rate, and runs
 * the MCU to the end of the period. Everything else is observed through simavr's IRQs:
 * interrupt entry/exit per vector, the tick-busy pin, the UART transmitter, the PWM pins.
 *
 * The host allocates as_size() bytes (8-byte aligned) per instance; simavr allocates the
 * MCU itself (as_close frees it).
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#include <simavr/avr_adc.h>
#include <simavr/avr_extint.h>
#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_interrupts.h>
#include <simavr/sim_irq.h>

#define AS_JOINTS 2
#define AS_EDGES 4096u
#define AS_RX 8192u
#define AS_TX 16384u
#define AS_VECTORS 64
#define AS_SUBSTEPS 64 /* Hermite path sampled this many times per period */
#define AS_PWM_PERIOD 510u /* Timer0 phase-correct 8-bit, no prescaler: 31.4 kHz */

enum { VS_COUNT, VS_CYCLES, VS_MAX_CYCLES, VS_MAX_LATENCY, VS_N };

/* Statistics (as_stats): indices of the int64 vector. */
enum {
    ST_CYCLE,
    ST_TICKS,         /* Timer1 compare matches */
    ST_WORK_N,        /* completed tick work (tick-busy pin falls) */
    ST_WORK_MAX,      /* cycles, Timer1 compare match -> end of the tick's work */
    ST_WORK_SUM,
    ST_LATE_OUTPUTS,  /* tick work not finished when the plant sampled the outputs */
    ST_TX_HWM,        /* firmware transmit ring: most bytes queued */
    ST_EDGES0,        /* quadrature edges put on the pins, joint 0 */
    ST_EDGES1,
    ST_COUNT_ERR_MAX, /* |firmware count - true count|, worst over checked ticks */
    ST_COUNT_ERR_TICKS,
    ST_TX_BYTES,
    ST_RX_BYTES,      /* host bytes put on the RX line */
    ST_TX_OVERFLOW,   /* shim buffer full (host did not collect) */
    ST_EDGE_OVERFLOW,
    ST_PWM_RISE0,     /* rising edges seen on the PWM pins */
    ST_PWM_RISE1,
    ST_PWM_LAST_HIGH0, /* last cycle the PWM pin was seen high (rise or still high) */
    ST_PWM_LAST_HIGH1,
    ST_ESTOP_CYCLE,   /* cycle the e-stop pin was pulled low (0: never) */
    ST_WORK_MAX_TICK, /* Timer1 compare match (1 = first) of the worst tick work */
    ST_LATE_TICKS,    /* compare matches raised before the previous tick's work ended */
    ST_LATE_FIRST,    /* the first such compare match (0: none) */
    ST_RESETS,        /* MCU resets after power-on (host DTR, watchdog) */
    ST_N
};

typedef struct {
    uint64_t cycle;
    int32_t count;
    uint8_t joint;
} as_edge_t;

typedef struct {
    /* pin map */
    char enc_port[AS_JOINTS];
    uint8_t enc_a[AS_JOINTS], enc_b[AS_JOINTS];
    char pwm_port[AS_JOINTS];
    uint8_t pwm_bit[AS_JOINTS];
    uint8_t dir_bit[AS_JOINTS]; /* PORTB */
    uint8_t estop_bit, busy_bit;  /* PORTB */
    uint8_t adc_i[AS_JOINTS], adc_v[AS_JOINTS];
    uint8_t vec_timer1, vec_pcint_enc;
    uint8_t own_pcint; /* simavr's model lacks the encoders' pin-change interrupt: add it */
    uint16_t reg_portb, reg_ocr0a, reg_ocr0b, reg_tccr0a;
    uint16_t pwm_ddr[AS_JOINTS]; /* data address of the PWM pin's DDR */
} as_pins_t;

typedef struct {
    avr_t *avr;
    elf_firmware_t fw;
    as_pins_t pins;
    uint64_t period;    /* cycles per tick */
    uint64_t latency;   /* L, cycles */
    uint64_t byte_cycles;
    uint64_t t1;        /* last Timer1 compare match */
    uint64_t t1_prev;
    int busy;           /* tick-busy pin level */
    int64_t work_n_at_t1; /* tick works completed at the last Timer1 compare match */
    /* plant -> analog */
    double fs_ma[AS_JOINTS], fs_mv[AS_JOINTS];
    double sigma_ma[AS_JOINTS], sigma_mv[AS_JOINTS]; /* per conversion */
    double supply_mv[AS_JOINTS];
    double ma[AS_JOINTS], mv[AS_JOINTS];             /* period means now on the inputs */
    uint64_t rng, seed;
    int noise;
    /* encoders */
    int32_t count[AS_JOINTS]; /* count now on the A/B pins */
    int32_t count0[AS_JOINTS];
    as_edge_t edge[AS_EDGES];
    as_edge_t joint_edge[AS_JOINTS][AS_EDGES / 2];
    uint32_t n_edges, next_edge;
    uint16_t ram_enc_count, ram_tx_head, ram_tx_tail, ram_overruns;
    /* UART */
    uint8_t rx[AS_RX];
    uint32_t rx_head, rx_len;
    int rx_timer_on, xoff;
    uint8_t tx[AS_TX];
    uint32_t tx_len;
    /* observations */
    int64_t st[ST_N];
    int64_t vs[AS_VECTORS][VS_N];
    uint64_t pend_since[AS_VECTORS], run_since[AS_VECTORS];
    int pwm_level[AS_JOINTS];
    uint64_t booted;
    avr_irq_t *enc_irq[AS_JOINTS][2];
    avr_irq_t *estop_irq;
    avr_irq_t *adc_irq;
    avr_irq_t *uart_irq;
    uint8_t pending[AS_VECTORS], running[AS_VECTORS];
    int32_t out[2 * AS_JOINTS];
    int vec_arg[AS_VECTORS];
    avr_int_vector_t pcint_enc; /* own_pcint */
    void (*core_reset)(struct avr_t *avr); /* the MCU model's own reset hook */
    int estop_down;                         /* the e-stop input is pressed */
    int redrive;                            /* a reset cleared the input pins */
} as_t;

/* avr->reset is called with the MCU only: the instance of each MCU (one per as_init). */
#define AS_MAX_INSTANCES 16
static struct {
    avr_t *avr;
    as_t *s;
} as_instances[AS_MAX_INSTANCES];

size_t as_size(void) { return sizeof(as_t); }

/* ------------------------------------------------------------------ helpers */
static double as_uniform(as_t *s) /* xorshift64*, (0, 1) */
{
    s->rng ^= s->rng >> 12;
    s->rng ^= s->rng << 25;
    s->rng ^= s->rng >> 27;
    return ((double)((s->rng * 2685821657736338717ULL) >> 11) + 0.5) / 9007199254740992.0;
}

static double as_gauss(as_t *s)
{
    double u = as_uniform(s), v = as_uniform(s);
    return sqrt(-2.0 * log(u)) * cos(6.283185307179586 * v);
}

static int32_t ram_i32(const as_t *s, uint16_t a)
{
    uint32_t v = 0u;
    int i;
    for (i = 3; i >= 0; --i)
        v = (v << 8) | s->avr->data[a + (unsigned)i];
    return (int32_t)v;
}

static void set_enc_pins(as_t *s, int j, int32_t count)
{
    /* count mod 4 -> AB: 0 -> 00, 1 -> 01, 2 -> 11, 3 -> 10 (A leads B going up) */
    static const uint8_t ab[4] = {0u, 1u, 3u, 2u};
    uint8_t v = ab[(uint32_t)count & 3u], mask = 0u, value = 0u;
    int k;
    s->count[j] = count;
    /* the encoder drives the lines: the input's pull-up must not win (simavr applies the
       "external" state of an input pin whenever the port is written) */
    for (k = 0; k < AS_JOINTS; ++k) {
        uint8_t w = ab[(uint32_t)s->count[k] & 3u];
        mask |= (uint8_t)((1u << s->pins.enc_a[k]) | (1u << s->pins.enc_b[k]));
        value |= (uint8_t)((((w >> 1) & 1u) << s->pins.enc_a[k]) | ((w & 1u) << s->pins.enc_b[k]));
    }
    {
        avr_ioport_external_t e;
        e.name = (unsigned char)s->pins.enc_port[j];
        e.mask = mask;
        e.value = value;
        avr_ioctl(s->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(s->pins.enc_port[j]), &e);
    }
    {
        uint8_t before = s->avr->data[0x106u]; /* PINK (ATmega2560) */
        avr_raise_irq(s->enc_irq[j][0], (v >> 1) & 1u);
        avr_raise_irq(s->enc_irq[j][1], v & 1u);
        if (s->pins.own_pcint && ((before ^ s->avr->data[0x106u]) & s->avr->data[0x6Du]))
            avr_raise_interrupt(s->avr, &s->pcint_enc);
    }
}

static void tx_sample(as_t *s)
{
    if (s->ram_tx_head) {
        int64_t q = (uint8_t)(s->avr->data[s->ram_tx_head] - s->avr->data[s->ram_tx_tail]) & 127;
        if (q > s->st[ST_TX_HWM])
            s->st[ST_TX_HWM] = q;
    }
}

/* ------------------------------------------------------------------ IRQ hooks */
/* Interrupt vectors: param points at s->vec_arg[v] (= v); recover the instance. */
static as_t *vec_owner(void *param, int *v)
{
    *v = *(int *)param;
    return (as_t *)(void *)((char *)param - offsetof(as_t, vec_arg) - (size_t)*v * sizeof(int));
}

static void on_pending(struct avr_irq_t *irq, uint32_t value, void *param)
{
    int v;
    as_t *s = vec_owner(param, &v);
    (void)irq;
    if (!value)
        return;
    s->pend_since[v] = s->avr->cycle;
    s->pending[v] = 1u;
    /* the firmware's tick: a boot loader may poll Timer1's flag with the interrupt off */
    if (v == s->pins.vec_timer1 && (s->avr->data[0x6Fu] & 0x02u)) { /* TIMSK1 OCIE1A */
        if (s->st[ST_TICKS] > 0 && (s->busy || s->st[ST_WORK_N] == s->work_n_at_t1)) {
            s->st[ST_LATE_TICKS]++;
            if (!s->st[ST_LATE_FIRST])
                s->st[ST_LATE_FIRST] = s->st[ST_TICKS] + 1;
        }
        s->st[ST_TICKS]++;
        s->work_n_at_t1 = s->st[ST_WORK_N];
        s->t1_prev = s->t1;
        s->t1 = s->avr->cycle;
    }
}

static void on_running(struct avr_irq_t *irq, uint32_t value, void *param)
{
    int v;
    as_t *s = vec_owner(param, &v);
    uint64_t now = s->avr->cycle;
    (void)irq;
    if (value) {
        int64_t lat = (int64_t)(now - s->pend_since[v]);
        s->run_since[v] = now;
        s->pending[v] = 0u;
        s->running[v] = 1u;
        s->vs[v][VS_COUNT]++;
        if (lat > s->vs[v][VS_MAX_LATENCY])
            s->vs[v][VS_MAX_LATENCY] = lat;
    } else {
        int64_t run = (int64_t)(now - s->run_since[v]);
        s->running[v] = 0u;
        s->vs[v][VS_CYCLES] += run;
        if (run > s->vs[v][VS_MAX_CYCLES])
            s->vs[v][VS_MAX_CYCLES] = run;
    }
}

static void on_busy(struct avr_irq_t *irq, uint32_t value, void *param)
{
    as_t *s = (as_t *)param;
    (void)irq;
    if (value && !s->busy) {
        s->busy = 1;
    } else if (!value && s->busy) {
        uint64_t work = s->avr->cycle - s->t1;
        s->busy = 0;
        s->st[ST_WORK_N]++;
        s->st[ST_WORK_SUM] += (int64_t)work;
        if ((int64_t)work > s->st[ST_WORK_MAX]) {
            s->st[ST_WORK_MAX] = (int64_t)work;
            s->st[ST_WORK_MAX_TICK] = s->st[ST_TICKS];
        }
        tx_sample(s);
    }
}

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    as_t *s = (as_t *)param;
    (void)irq;
    s->st[ST_TX_BYTES]++;
    if (s->tx_len < AS_TX)
        s->tx[s->tx_len++] = (uint8_t)value;
    else
        s->st[ST_TX_OVERFLOW]++;
    tx_sample(s);
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    ((as_t *)param)->xoff = 0;
}

static void on_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    ((as_t *)param)->xoff = 1;
}

/* A conversion starts: put the front end's output for its channel on the pin. */
static void on_adc_trigger(struct avr_irq_t *irq, uint32_t value, void *param)
{
    as_t *s = (as_t *)param;
    union {
        avr_adc_mux_t mux;
        uint32_t v;
    } e;
    unsigned src;
    int j;
    double code = 512.0;
    (void)irq;
    e.v = value;
    src = (unsigned)e.mux.src;
    for (j = 0; j < AS_JOINTS; ++j) {
        if (src == s->pins.adc_i[j])
            code = 512.0 + 512.0 * (s->ma[j] + (s->noise ? s->sigma_ma[j] * as_gauss(s) : 0.0)) /
                               s->fs_ma[j];
        else if (src == s->pins.adc_v[j])
            code = 512.0 + 512.0 * (s->mv[j] + (s->noise ? s->sigma_mv[j] * as_gauss(s) : 0.0)) /
                               s->fs_mv[j];
    }
    {
        /* the 10-bit ADC's code of that analog value, as integer millivolts that simavr's
           conversion (mV * 1023 / AVcc, truncated) maps back to exactly that code */
        double c = floor(code);
        uint32_t mv;
        c = c < 0.0 ? 0.0 : (c > 1023.0 ? 1023.0 : c);
        mv = (uint32_t)ceil(c * (double)s->avr->avcc / 1023.0);
        avr_raise_irq(s->adc_irq + ADC_IRQ_ADC0 + src, mv);
    }
}

/* ------------------------------------------------------------------ cycle timers */
/* The PWM outputs once per PWM period: simavr 1.6 does not drive the OC0A/OC0B pins in
   phase-correct mode, so the pin's duty is formed as the hardware does: compare output
   connected (COM0x1), pin an output (DDR) and OCR0x > 0 -> the pin is high for OCR0x/255 of
   the period. Records the last cycle each PWM pin was high and its off -> on switches. */
static avr_cycle_count_t pwm_timer(struct avr_t *avr, avr_cycle_count_t when, void *param)
{
    as_t *s = (as_t *)param;
    const uint8_t *d = avr->data;
    static const uint8_t com[AS_JOINTS] = {0x80u, 0x20u};
    int j;
    for (j = 0; j < AS_JOINTS; ++j) {
        uint8_t ocr = d[j == 0 ? s->pins.reg_ocr0a : s->pins.reg_ocr0b];
        int on = ocr > 0u && (d[s->pins.reg_tccr0a] & com[j]) &&
                 (d[s->pins.pwm_ddr[j]] & (1u << s->pins.pwm_bit[j]));
        if (on) {
            if (!s->pwm_level[j])
                s->st[ST_PWM_RISE0 + j]++;
            s->st[ST_PWM_LAST_HIGH0 + j] = (int64_t)when;
        }
        s->pwm_level[j] = on;
    }
    return when + AS_PWM_PERIOD;
}

static avr_cycle_count_t edge_timer(struct avr_t *avr, avr_cycle_count_t when, void *param)
{
    as_t *s = (as_t *)param;
    (void)when;
    while (s->next_edge < s->n_edges && s->edge[s->next_edge].cycle <= avr->cycle) {
        const as_edge_t *e = &s->edge[s->next_edge++];
        set_enc_pins(s, e->joint, e->count);
        s->st[ST_EDGES0 + e->joint]++;
    }
    return s->next_edge < s->n_edges ? s->edge[s->next_edge].cycle : 0u;
}

static avr_cycle_count_t rx_timer(struct avr_t *avr, avr_cycle_count_t when, void *param)
{
    as_t *s = (as_t *)param;
    (void)avr;
    if (s->rx_len == 0u) {
        s->rx_timer_on = 0;
        return 0u;
    }
    if (!s->xoff) {
        avr_raise_irq(s->uart_irq + UART_IRQ_INPUT, s->rx[s->rx_head]);
        s->rx_head = (s->rx_head + 1u) % AS_RX;
        s->rx_len--;
        s->st[ST_RX_BYTES]++;
    }
    return when + s->byte_cycles;
}

static void drive_estop(as_t *s, int pressed);

/* ------------------------------------------------------------------ set-up */
/* The MCU sleeps (idle main loop): jump to the next event at once. simavr's default
   sleep callback waits out the sleep in wall-clock time. */
static void no_wait(struct avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr;
    (void)how_long;
}

static avr_cycle_count_t stop_timer(struct avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    (void)when;
    (void)param;
    return 0u;
}

static void quiet_logger(struct avr_t *avr, const int level, const char *format, va_list ap)
{
    (void)avr;
    (void)level;
    (void)format;
    (void)ap;
}

static int pin_map(as_pins_t *p, int mcu)
{
    memset(p, 0, sizeof *p);
    p->dir_bit[0] = 0u;
    p->dir_bit[1] = 1u;
    p->adc_i[0] = 0u;
    p->adc_i[1] = 1u;
    p->adc_v[0] = 2u;
    p->adc_v[1] = 3u;
    p->reg_portb = 0x25u;
    p->reg_ocr0a = 0x47u;
    p->reg_ocr0b = 0x48u;
    p->reg_tccr0a = 0x44u;
    if (mcu == 0) { /* ATmega328P (board.h) */
        p->enc_port[0] = p->enc_port[1] = 'D';
        p->enc_a[0] = 2u;
        p->enc_b[0] = 3u;
        p->enc_a[1] = 4u;
        p->enc_b[1] = 7u;
        p->pwm_port[0] = p->pwm_port[1] = 'D';
        p->pwm_bit[0] = 6u;
        p->pwm_bit[1] = 5u;
        p->pwm_ddr[0] = p->pwm_ddr[1] = 0x2Au; /* DDRD */
        p->estop_bit = 2u;
        p->busy_bit = 3u;
        p->vec_timer1 = 11u;
        p->vec_pcint_enc = 5u;
        return 0;
    }
    if (mcu == 1) { /* ATmega2560 */
        p->enc_port[0] = p->enc_port[1] = 'K';
        p->enc_a[0] = 0u;
        p->enc_b[0] = 1u;
        p->enc_a[1] = 2u;
        p->enc_b[1] = 3u;
        p->pwm_port[0] = 'B';
        p->pwm_bit[0] = 7u;
        p->pwm_port[1] = 'G';
        p->pwm_bit[1] = 5u;
        p->pwm_ddr[0] = 0x24u; /* DDRB */
        p->pwm_ddr[1] = 0x33u; /* DDRG */
        p->estop_bit = 4u;
        p->busy_bit = 6u;
        p->vec_timer1 = 17u;
        p->vec_pcint_enc = 11u;
        p->own_pcint = 1u; /* PCINT16..23 on port K: PCICR 0x68 / PCIFR 0x3B bit 2, PCMSK2 0x6D */
        return 0;
    }
    return -1;
}


static avr_cycle_count_t pwm_timer(struct avr_t *avr, avr_cycle_count_t when, void *param);
static avr_cycle_count_t rx_timer(struct avr_t *avr, avr_cycle_count_t when, void *param);

/* The wires still carry the encoders and the e-stop after a reset of the MCU's ports. */
static void redrive_pins(as_t *s)
{
    int j, k;
    s->redrive = 0;
    avr_extint_set_strict_lvl_trig(s->avr, 0, 0); /* the reset set them again (as_init) */
    avr_extint_set_strict_lvl_trig(s->avr, 1, 0);
    /* simavr drops a pin IRQ raised at the value it holds, which the port's reset left
       while clearing the register: make every level count as a change */
    for (j = 0; j < AS_JOINTS; ++j)
        for (k = 0; k < 2; ++k)
            s->enc_irq[j][k]->value = ~0u;
    s->estop_irq->value = ~0u;
    for (j = 0; j < AS_JOINTS; ++j)
        set_enc_pins(s, j, s->count[j]);
    drive_estop(s, s->estop_down);
}

/* After any reset (simavr cleared every cycle timer): the PWM sampler and the RX pacing run
   again, the tick bookkeeping starts over (t1 = 0: booting until the first tick). */
static void on_reset(struct avr_t *avr)
{
    as_t *s = NULL;
    int i;
    for (i = 0; i < AS_MAX_INSTANCES; ++i)
        if (as_instances[i].avr == avr)
            s = as_instances[i].s;
    if (!s)
        return;
    if (s->core_reset)
        s->core_reset(avr);
    s->st[ST_RESETS]++;
    s->t1 = s->t1_prev = 0u;
    s->busy = 0;
    s->xoff = 0;
    s->n_edges = s->next_edge = 0u;
    s->redrive = 1; /* after the ports' own reset (run_to) */
    avr_cycle_timer_register(avr, AS_PWM_PERIOD, pwm_timer, s);
    s->rx_timer_on = s->rx_len > 0u;
    if (s->rx_timer_on)
        avr_cycle_timer_register(avr, 1u, rx_timer, s);
}

/* Put a boot loader image (bytes at byte address base) into the boot section and start
   there, as the BOOTRST fuse does: 0, or -3 outside the flash. */
static int load_boot_loader(as_t *s, const uint8_t *image, size_t size, uint32_t base)
{
    if (size == 0u || base > s->avr->flashend)
        return -3;
    if ((size_t)base + size > (size_t)s->avr->flashend + 1u) /* a stray record past the end */
        size = (size_t)s->avr->flashend + 1u - base;
    memcpy(s->avr->flash + base, image, size);
    s->avr->reset_pc = base;
    s->avr->pc = base;
    s->avr->codeend = s->avr->flashend;
    return 0;
}

/* The host pulls DTR: the auto-reset capacitor pulses RESET (an external reset). */
static void set_external_reset_flag(as_t *s)
{
    avr_regbit_t r = s->avr->reset_flags.extrf;
    s->avr->data[r.reg] = (uint8_t)(1u << r.bit);
}

/* power_cycle: the robot is back at its start too (encoder pins at their first counts,
   sensors at 0, the noise stream from its seed), as at as_init. */
void as_reset(as_t *s, int power_cycle)
{
    if (power_cycle) {
        int j;
        for (j = 0; j < AS_JOINTS; ++j) {
            s->count[j] = s->count0[j];
            s->ma[j] = s->mv[j] = 0.0;
        }
        s->rng = s->seed;
    }
    avr_reset(s->avr);
    set_external_reset_flag(s);
}

/* cfg (doubles): f_cpu [Hz], tick [cycles], latency L [cycles], avcc [mV], baud [bit/s],
   seed, noise (0/1), RAM addresses of enc_count, tx_head, tx_tail (0: unknown), then per
   joint: supply [mV], current full scale [mA], voltage full scale [mV], noise sigma per
   conversion of current [mA] and voltage [mV], initial count.
   boot (boot_size bytes at byte address boot_base): a boot loader image run from reset
   before the firmware (boot_size 0: none).
   Returns 0, or -1 bad arguments, -2 unknown MCU, -3 ELF or boot loader unreadable,
   -7 too many instances. */
#define AS_CFG_FIXED 10u
#define AS_CFG_JOINT 6u
int as_init(as_t *s, const char *elf, const uint8_t *boot, size_t boot_size, double boot_base,
            int mcu, const double *cfg, size_t n)
{
    static const char *names[] = {"atmega328p", "atmega2560"};
    int j;
    uint32_t flags = 0u, i;
    memset(s, 0, sizeof *s);
    if (n != AS_CFG_FIXED + AS_CFG_JOINT * AS_JOINTS)
        return -1;
    if (pin_map(&s->pins, mcu) != 0)
        return -2;
    for (i = 0; i < AS_VECTORS; ++i)
        s->vec_arg[i] = (int)i;
    avr_global_logger_set(quiet_logger); /* the host reports errors, not simavr's console */
    if (elf_read_firmware(elf, &s->fw) != 0)
        return -3;
    s->avr = avr_make_mcu_by_name(names[mcu]);
    if (!s->avr)
        return -2;
    avr_init(s->avr);
    s->avr->log = LOG_NONE;
    s->avr->sleep = no_wait;
    /* INT0/INT1 (PD2/PD3: encoder 0 on the ATmega328P) are not used by the firmware
       (EIMSK = 0), but simavr polls a low level on them every cycle for "strict" level
       triggering: off, or the simulation steps two cycles at a time while the MCU sleeps. */
    avr_extint_set_strict_lvl_trig(s->avr, 0, 0);
    avr_extint_set_strict_lvl_trig(s->avr, 1, 0);
    s->fw.frequency = (uint32_t)cfg[0];
    avr_load_firmware(s->avr, &s->fw);
    s->avr->frequency = (uint32_t)cfg[0];
    if (boot_size) {
        if (load_boot_loader(s, boot, boot_size, (uint32_t)boot_base) != 0)
            return -3;
        set_external_reset_flag(s); /* the host's open pulsed DTR */
    }
    for (i = 0; i < AS_MAX_INSTANCES && as_instances[i].avr; ++i)
        ;
    if (i == AS_MAX_INSTANCES)
        return -7;
    as_instances[i].avr = s->avr;
    as_instances[i].s = s;
    s->core_reset = s->avr->reset;
    s->avr->reset = on_reset;
    s->period = (uint64_t)cfg[1];
    s->latency = (uint64_t)cfg[2];
    s->avr->avcc = s->avr->vcc = s->avr->aref = (uint32_t)cfg[3];
    s->byte_cycles = (uint64_t)ceil(cfg[0] * 10.0 / cfg[4]);
    s->rng = s->seed = (uint64_t)cfg[5] * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL;
    s->noise = cfg[6] != 0.0;
    s->ram_enc_count = (uint16_t)cfg[7];
    s->ram_tx_head = (uint16_t)cfg[8];
    s->ram_tx_tail = (uint16_t)cfg[9];
    for (j = 0; j < AS_JOINTS; ++j) {
        const double *v = cfg + AS_CFG_FIXED + AS_CFG_JOINT * (size_t)j;
        s->supply_mv[j] = v[0];
        s->fs_ma[j] = v[1];
        s->fs_mv[j] = v[2];
        s->sigma_ma[j] = v[3];
        s->sigma_mv[j] = v[4];
        s->count0[j] = (int32_t)v[5];
    }
    if (s->pins.own_pcint) {
        avr_regbit_t en = AVR_IO_REGBIT(0x68, 2), fl = AVR_IO_REGBIT(0x3B, 2);
        s->pcint_enc.vector = s->pins.vec_pcint_enc;
        s->pcint_enc.enable = en;
        s->pcint_enc.raised = fl;
        avr_register_vector(s->avr, &s->pcint_enc);
    }
    /* interrupts: entry / exit of every vector */
    for (i = 0; i < s->avr->interrupts.vector_count; ++i) {
        avr_int_vector_t *vec = s->avr->interrupts.vector[i];
        if (vec->vector >= AS_VECTORS)
            continue;
        avr_irq_register_notify(vec->irq + AVR_INT_IRQ_PENDING, on_pending,
                                &s->vec_arg[vec->vector]);
        avr_irq_register_notify(vec->irq + AVR_INT_IRQ_RUNNING, on_running,
                                &s->vec_arg[vec->vector]);
    }
    /* pins */
    for (j = 0; j < AS_JOINTS; ++j) {
        s->enc_irq[j][0] =
            avr_io_getirq(s->avr, AVR_IOCTL_IOPORT_GETIRQ(s->pins.enc_port[j]), s->pins.enc_a[j]);
        s->enc_irq[j][1] =
            avr_io_getirq(s->avr, AVR_IOCTL_IOPORT_GETIRQ(s->pins.enc_port[j]), s->pins.enc_b[j]);
        set_enc_pins(s, j, s->count0[j]);
    }
    avr_cycle_timer_register(s->avr, AS_PWM_PERIOD, pwm_timer, s);
    avr_irq_register_notify(avr_io_getirq(s->avr, AVR_IOCTL_IOPORT_GETIRQ('B'), s->pins.busy_bit),
                            on_busy, s);
    s->estop_irq = avr_io_getirq(s->avr, AVR_IOCTL_IOPORT_GETIRQ('B'), s->pins.estop_bit);
    drive_estop(s, 0);
    /* ADC */
    s->adc_irq = avr_io_getirq(s->avr, AVR_IOCTL_ADC_GETIRQ, 0);
    avr_irq_register_notify(s->adc_irq + ADC_IRQ_OUT_TRIGGER, on_adc_trigger, s);
    /* UART 0: no console echo, no host sleeping while the firmware polls */
    s->uart_irq = avr_io_getirq(s->avr, AVR_IOCTL_UART_GETIRQ('0'), 0);
    avr_ioctl(s->avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(s->avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(s->uart_irq + UART_IRQ_OUTPUT, on_uart_out, s);
    avr_irq_register_notify(s->uart_irq + UART_IRQ_OUT_XON, on_xon, s);
    avr_irq_register_notify(s->uart_irq + UART_IRQ_OUT_XOFF, on_xoff, s);
    for (j = 0; j < AS_JOINTS; ++j) {
        s->ma[j] = 0.0;
        s->mv[j] = 0.0;
    }
    return 0;
}

void as_close(as_t *s)
{
    if (s->avr) {
        int i;
        for (i = 0; i < AS_MAX_INSTANCES; ++i)
            if (as_instances[i].avr == s->avr)
                as_instances[i].avr = NULL;
        avr_terminate(s->avr);
        free(s->avr);
        s->avr = NULL;
    }
    free(s->fw.flash);
    free(s->fw.eeprom);
    s->fw.flash = NULL;
    s->fw.eeprom = NULL;
}

static void sample_outputs(as_t *s)
{
    const uint8_t *d = s->avr->data;
    s->out[0] = d[s->pins.reg_ocr0a];
    s->out[1] = (d[s->pins.reg_portb] >> s->pins.dir_bit[0]) & 1;
    s->out[2] = d[s->pins.reg_ocr0b];
    s->out[3] = (d[s->pins.reg_portb] >> s->pins.dir_bit[1]) & 1;
    if (s->busy)
        s->st[ST_LATE_OUTPUTS]++;
}

/* Run to `target` cycles; 0, or -1 if the core stopped or crashed. */
static int run_to(as_t *s, uint64_t target)
{
    if (target > s->avr->cycle) /* a sleeping MCU wakes there, not past it */
        avr_cycle_timer_register(s->avr, target - s->avr->cycle, stop_timer, s);
    while (s->avr->cycle < target) {
        int state = avr_run(s->avr);
        if (state == cpu_Done || state == cpu_Crashed)
            return -1;
        if (s->redrive)
            redrive_pins(s);
    }
    s->st[ST_CYCLE] = (int64_t)s->avr->cycle;
    return 0;
}

/* Boot: run until the first tick interrupt plus L (at most max_cycles). 0, -1 crashed,
   -4 no tick interrupt. The boot output stays in the transmit buffer. */
int as_boot(as_t *s, double max_cycles)
{
    uint64_t limit = (uint64_t)max_cycles;
    while (s->t1 == 0u) {
        if (s->avr->cycle >= limit)
            return -4;
        if (run_to(s, s->avr->cycle + 1u) != 0)
            return -1;
    }
    if (run_to(s, s->t1 + s->latency) != 0)
        return -1;
    sample_outputs(s);
    return 0;
}

/* Booting (boot loader, firmware set-up; no plant): run `cycles` more cycles or until the
   first tick interrupt plus L. 1 the tick runs (outputs sampled), 0 still booting, -1
   crashed. */
int as_boot_step(as_t *s, double cycles)
{
    uint64_t end = s->avr->cycle + (uint64_t)cycles;
    while (s->t1 == 0u && s->avr->cycle < end) {
        uint64_t next = s->avr->cycle + 1024u;
        if (run_to(s, next < end ? next : end) != 0)
            return -1;
    }
    if (s->t1 == 0u)
        return 0;
    if (run_to(s, s->t1 + s->latency) != 0)
        return -1;
    if (s->t1 == 0u) /* reset again meanwhile */
        return 0;
    sample_outputs(s);
    return 1;
}

/* The edges of one joint over one period: x0, x1 [counts], v0, v1 [counts/s], from the
   current pin count; written to out (sorted), returns their number (or cap + 1). */
static uint32_t joint_edges(as_t *s, int j, const double *p, uint64_t start, as_edge_t *out,
                            uint32_t cap)
{
    double span = (double)s->period;
    double m0 = p[1] * span / (double)s->avr->frequency;
    double m1 = p[3] * span / (double)s->avr->frequency;
    double xa = p[0], sa = 0.0;
    int32_t c = s->count[j];
    uint64_t last = start;
    uint32_t n = 0u;
    int k;
    for (k = 1; k <= AS_SUBSTEPS; ++k) {
        double t = (double)k / AS_SUBSTEPS, t2 = t * t, t3 = t2 * t;
        double xb = (2 * t3 - 3 * t2 + 1) * p[0] + (t3 - 2 * t2 + t) * m0 +
                    (-2 * t3 + 3 * t2) * p[2] + (t3 - t2) * m1;
        if (k == AS_SUBSTEPS)
            xb = p[2];
        while (floor(xb) != (double)c) {
            int up = floor(xb) > (double)c;
            double boundary = up ? (double)c + 1.0 : (double)c;
            double frac = xb != xa ? (boundary - xa) / (xb - xa) : 1.0;
            uint64_t cyc;
            frac = frac < 0.0 ? 0.0 : (frac > 1.0 ? 1.0 : frac);
            cyc = start + (uint64_t)floor((sa + frac * (t - sa)) * span);
            if (cyc <= last && n > 0u)
                cyc = last + 1u;
            if (n >= cap)
                return cap + 1u;
            c += up ? 1 : -1;
            out[n].cycle = cyc;
            out[n].count = c;
            out[n].joint = (uint8_t)j;
            last = cyc;
            n++;
        }
        xa = xb;
        sa = t;
    }
    return n;
}

/* One plant period. plant: per joint x0, v0, x1, v1 (encoder counts, counts/s), period-mean
   current [mA] and voltage [mV]. Returns 0, -1 crashed, -4 the tick interrupt stopped,
   -5 too many edges, -6 the MCU was reset (booting again: as_boot_step). */
int as_run_tick(as_t *s, const double *plant)
{
    uint32_t n[AS_JOINTS], a = 0u, b = 0u, k = 0u;
    uint64_t t1 = s->t1, start = t1 + s->latency;
    int64_t resets;
    int j, rc;
    for (j = 0; j < AS_JOINTS; ++j) {
        const double *p = plant + 6 * j;
        n[j] = joint_edges(s, j, p, start, s->joint_edge[j], AS_EDGES / 2);
        if (n[j] > AS_EDGES / 2) {
            s->st[ST_EDGE_OVERFLOW]++;
            return -5;
        }
        s->ma[j] = p[4];
        s->mv[j] = p[5];
    }
    while (a < n[0] || b < n[1]) /* merge by cycle */
        s->edge[k++] = (b >= n[1] || (a < n[0] && s->joint_edge[0][a].cycle <= s->joint_edge[1][b].cycle))
                           ? s->joint_edge[0][a++]
                           : s->joint_edge[1][b++];
    s->n_edges = k;
    s->next_edge = 0u;
    avr_cycle_timer_cancel(s->avr, edge_timer, s);
    if (k > 0u) {
        uint64_t first = s->edge[0].cycle;
        avr_cycle_timer_register(s->avr, first > s->avr->cycle ? first - s->avr->cycle : 0u,
                                 edge_timer, s);
    }
    resets = s->st[ST_RESETS];
    rc = run_to(s, t1 + s->period + s->latency);
    if (rc != 0)
        return rc;
    if (s->st[ST_RESETS] != resets)
        return -6;
    if (s->t1 == t1)
        return -4;
    if (s->next_edge < s->n_edges) /* edges scheduled past the period's end (rounding) */
        edge_timer(s->avr, s->avr->cycle, s);
    sample_outputs(s);
    if (s->ram_enc_count && !s->pending[s->pins.vec_pcint_enc] &&
        !s->running[s->pins.vec_pcint_enc]) {
        int64_t worst = 0;
        for (j = 0; j < AS_JOINTS; ++j) {
            int64_t err = (int64_t)ram_i32(s, (uint16_t)(s->ram_enc_count + 4u * (unsigned)j)) -
                          (int64_t)(s->count[j] - s->count0[j]);
            err = err < 0 ? -err : err;
            worst = err > worst ? err : worst;
        }
        if (worst > 0)
            s->st[ST_COUNT_ERR_TICKS]++;
        if (worst > s->st[ST_COUNT_ERR_MAX])
            s->st[ST_COUNT_ERR_MAX] = worst;
    }
    return 0;
}

/* PWM duty (OCR0A/B) and DIR pin per joint at the last output sample: duty0, dir0, ... */
void as_outputs(const as_t *s, int32_t *out)
{
    int i;
    for (i = 0; i < 2 * AS_JOINTS; ++i)
        out[i] = s->out[i];
}

/* Queue host bytes for the RX line (paced at the baud rate); returns how many fit. */
size_t as_rx_push(as_t *s, const uint8_t *data, size_t len)
{
    size_t i;
    for (i = 0; i < len && s->rx_len < AS_RX; ++i) {
        s->rx[(s->rx_head + s->rx_len) % AS_RX] = data[i];
        s->rx_len++;
    }
    if (s->rx_len > 0u && !s->rx_timer_on) {
        s->rx_timer_on = 1;
        avr_cycle_timer_register(s->avr, 1u, rx_timer, s);
    }
    return i;
}

size_t as_rx_pending(const as_t *s) { return s->rx_len; }

/* Bytes the MCU transmitted (copied out and forgotten); returns their count. */
size_t as_tx_take(as_t *s, uint8_t *buf, size_t cap)
{
    size_t n = s->tx_len < cap ? s->tx_len : cap, i;
    memcpy(buf, s->tx, n);
    for (i = n; i < s->tx_len; ++i)
        s->tx[i - n] = s->tx[i];
    s->tx_len -= (uint32_t)n;
    return n;
}

/* The e-stop input: pressed (pin pulled low) or released. */
static void drive_estop(as_t *s, int pressed)
{
    avr_ioport_external_t e;
    s->estop_down = pressed;
    e.name = 'B';
    e.mask = (uint8_t)(1u << s->pins.estop_bit);
    e.value = pressed ? 0u : e.mask;
    avr_ioctl(s->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL('B'), &e);
    avr_raise_irq(s->estop_irq, pressed ? 0u : 1u);
}

void as_estop(as_t *s, int pressed)
{
    drive_estop(s, pressed);
    if (pressed)
        s->st[ST_ESTOP_CYCLE] = (int64_t)s->avr->cycle;
}

/* Statistics: st[ST_N], vs[64][4] (count, cycles, max cycles, max latency per vector). */
void as_stats(const as_t *s, int64_t *st, int64_t *vs)
{
    int i, k;
    for (i = 0; i < ST_N; ++i)
        st[i] = s->st[i];
    for (i = 0; i < AS_VECTORS; ++i)
        for (k = 0; k < VS_N; ++k)
            vs[i * VS_N + k] = s->vs[i][k];
}

int as_stat_count(void) { return ST_N; }

/* Copy n bytes of the MCU's data space from addr (tests, diagnostics). */
void as_read_ram(const as_t *s, unsigned addr, uint8_t *buf, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i)
        buf[i] = s->avr->data[addr + i];
}

/* The count now on the encoder pins of each joint, relative to the start. */
void as_pin_counts(const as_t *s, int32_t *out)
{
    int j;
    for (j = 0; j < AS_JOINTS; ++j)
        out[j] = s->count[j] - s->count0[j];
}

/* Copy n bytes of the MCU's flash from byte address addr (what a boot loader wrote). */
int as_read_flash(const as_t *s, unsigned addr, uint8_t *buf, size_t n)
{
    if ((size_t)addr + n > (size_t)s->avr->flashend + 1u)
        return -1;
    memcpy(buf, s->avr->flash + addr, n);
    return 0;
}
