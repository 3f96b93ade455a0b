/* hal_avr.c: the guard_fw hardware layer on an ATmega328P / ATmega2560 (see board.h).
 *
 * Timer1 (CTC) gives the 15 ms tick; its interrupt latches the encoder counts and the ADC
 * sums of the period that just ended, so that gf_tick() (main loop) sees one consistent
 * snapshot. Timer0 drives both motors' PWM (8-bit, phase correct, 31 kHz). The ADC runs
 * continuously in its interrupt over four channels (oversampling: about 36 conversions per
 * channel and tick); the period mean is formed in the main loop. Encoders: pin-change
 * interrupt, 4x quadrature decoding. UART: interrupt-driven ring buffers.
 */
#include <avr/interrupt.h>
#include <avr/io.h>

#include "board.h"

#if defined(__AVR_ATmega2560__)
#define UART_RX_VECT USART0_RX_vect
#define UART_UDRE_VECT USART0_UDRE_vect
#define ENC_PIN PINK
#define ENC_PORT PORTK
#define ENC_DDR DDRK
#define ENC_A0 0
#define ENC_B0 1
#define ENC_A1 2
#define ENC_B1 3
#define ENC_PCMSK_BITS ((1u << PCINT16) | (1u << PCINT17) | (1u << PCINT18) | (1u << PCINT19))
#define PWM_SETUP()                                                                           \
    do {                                                                                      \
        DDRB |= (uint8_t)(1u << PB7);                                                         \
        DDRG |= (uint8_t)(1u << PG5);                                                         \
    } while (0)
#define ESTOP_BIT PB4
#define ESTOP_PCINT PCINT4
#elif defined(__AVR_ATmega328P__)
#define UART_RX_VECT USART_RX_vect
#define UART_UDRE_VECT USART_UDRE_vect
#define ENC_PIN PIND
#define ENC_PORT PORTD
#define ENC_DDR DDRD
#define ENC_A0 2
#define ENC_B0 3
#define ENC_A1 4
#define ENC_B1 7
#define ENC_PCMSK_BITS ((1u << PCINT18) | (1u << PCINT19) | (1u << PCINT20) | (1u << PCINT23))
#define PWM_SETUP()                                                                           \
    do {                                                                                      \
        DDRD |= (uint8_t)((1u << PD6) | (1u << PD5));                                         \
    } while (0)
#define ESTOP_BIT PB2
#define ESTOP_PCINT PCINT2
#else
#error "board: ATmega328P or ATmega2560 only (add a pin map for another MCU)"
#endif

#define DIR0_BIT PB0
#define DIR1_BIT PB1
#define N_ADC 4u
#define RX_SIZE 64u  /* power of two */
#define TX_SIZE 128u /* power of two; the core waits while it is full */

/* ------------------------------------------------------------------ shared with ISRs */
static volatile int32_t enc_count[2];
static volatile uint8_t enc_prev[2];
static volatile uint16_t adc_sum[N_ADC];
static volatile uint8_t adc_n[N_ADC];
static volatile uint8_t adc_ch;
static volatile uint8_t tick_pending;
static volatile uint8_t estop_fired;
static volatile uint8_t rx_buf[RX_SIZE];
static volatile uint8_t rx_head, rx_tail;
static volatile uint8_t tx_buf[TX_SIZE];
static volatile uint8_t tx_head, tx_tail;

/* latched by the tick interrupt */
static volatile int32_t tick_counts[2];
static volatile uint16_t tick_sum[N_ADC];
static volatile uint8_t tick_n[N_ADC];

static const int32_t current_fs_ma[2] = BOARD_CURRENT_FS_MA;
static const int32_t voltage_fs_mv[2] = BOARD_VOLTAGE_FS_MV;
static const uint8_t ch_current[2] = {BOARD_ADC_CH_CURRENT0, BOARD_ADC_CH_CURRENT1};
static const uint8_t ch_voltage[2] = {BOARD_ADC_CH_VOLTAGE0, BOARD_ADC_CH_VOLTAGE1};

/* main-loop copy for gf_tick */
static int32_t snap_counts[2];
static int32_t snap_mv[2], snap_ma[2];
static volatile uint16_t overruns;

/* ------------------------------------------------------------------ interrupts */
/* (previous AB << 2 | current AB) -> step */
static const int8_t qdec[16] = {0, 1, -1, 0, -1, 0, 0, 1, 1, 0, 0, -1, 0, -1, 1, 0};

ISR(PCINT2_vect)
{
    uint8_t pins = ENC_PIN;
    uint8_t ab0 = (uint8_t)((((pins >> ENC_A0) & 1u) << 1) | ((pins >> ENC_B0) & 1u));
    uint8_t ab1 = (uint8_t)((((pins >> ENC_A1) & 1u) << 1) | ((pins >> ENC_B1) & 1u));
    enc_count[0] += BOARD_ENC0_SIGN * qdec[(enc_prev[0] << 2) | ab0];
    enc_count[1] += BOARD_ENC1_SIGN * qdec[(enc_prev[1] << 2) | ab1];
    enc_prev[0] = ab0;
    enc_prev[1] = ab1;
}

ISR(PCINT0_vect) /* e-stop input: cut the motors here, the core latches in the main loop */
{
    if (!(PINB & (1u << ESTOP_BIT))) {
        OCR0A = 0u;
        OCR0B = 0u;
        estop_fired = 1u;
    }
}

ISR(TIMER1_COMPA_vect)
{
    uint8_t i;
    tick_counts[0] = enc_count[0]; /* encoder ISR cannot interrupt us: consistent */
    tick_counts[1] = enc_count[1];
    for (i = 0; i < N_ADC; ++i) {
        tick_sum[i] = adc_sum[i];
        tick_n[i] = adc_n[i];
        adc_sum[i] = 0u;
        adc_n[i] = 0u;
    }
    if (tick_pending)
        overruns++;
    tick_pending = 1u;
}

ISR(ADC_vect)
{
    uint8_t ch = adc_ch;
    adc_sum[ch] += ADC;
    adc_n[ch]++;
    ch = (uint8_t)((ch + 1u) % N_ADC);
    adc_ch = ch;
    ADMUX = (uint8_t)((1u << REFS0) | ch);
    ADCSRA |= (uint8_t)(1u << ADSC);
}

ISR(UART_RX_VECT)
{
    uint8_t b = UDR0;
    uint8_t next = (uint8_t)((rx_head + 1u) & (RX_SIZE - 1u));
    if (next != rx_tail) { /* full: the byte is lost, the parser resynchronises */
        rx_buf[rx_head] = b;
        rx_head = next;
    }
}

ISR(UART_UDRE_VECT)
{
    if (tx_head == tx_tail) {
        UCSR0B &= (uint8_t)~(1u << UDRIE0);
    } else {
        UDR0 = tx_buf[tx_tail];
        tx_tail = (uint8_t)((tx_tail + 1u) & (TX_SIZE - 1u));
    }
}

/* ------------------------------------------------------------------ HAL for guard_fw */
static int32_t round_div(int32_t num, int32_t den) /* den > 0, half away from zero */
{
    return num >= 0 ? (num + den / 2) / den : -((-num + den / 2) / den);
}

/* Period mean of n conversions summing to sum, centred at 512 codes, 512 codes = fs.
   The ADC truncates (code c covers c .. c + 1 LSB of input): over noisy conversions the
   mean code is half an LSB below the input, so half a code per conversion is added back
   (2 sum + n - 1024 n: |.| <= 1024 n <= 2^17 for n <= 128, times fs <= 16000 fits int32). */
static int32_t adc_mean(uint16_t sum, uint8_t n, int32_t fs)
{
    if (n == 0u)
        return 0;
    return round_div((2L * (int32_t)sum + (int32_t)n - 1024L * n) * fs, 1024L * n);
}

static int32_t hal_read_counts(void *ctx, uint8_t joint)
{
    (void)ctx;
    return snap_counts[joint];
}

static void hal_read_adc(void *ctx, uint8_t joint, int32_t *mv, int32_t *ma)
{
    (void)ctx;
    *mv = snap_mv[joint];
    *ma = snap_ma[joint];
}

static void hal_set_output(void *ctx, uint8_t joint, int32_t mv, uint16_t duty)
{
    uint8_t d = duty > 255u ? 255u : (uint8_t)duty;
    uint8_t bit = joint == 0u ? (uint8_t)(1u << DIR0_BIT) : (uint8_t)(1u << DIR1_BIT);
    (void)ctx;
    if (mv < 0)
        PORTB |= bit;
    else
        PORTB &= (uint8_t)~bit;
    if (joint == 0u)
        OCR0A = d;
    else
        OCR0B = d;
}

static void hal_uart_write(void *ctx, const uint8_t *data, size_t len)
{
    size_t i;
    (void)ctx;
    for (i = 0; i < len; ++i) {
        uint8_t next = (uint8_t)((tx_head + 1u) & (TX_SIZE - 1u));
        while (next == tx_tail) {
            /* full: the UDRE interrupt drains it (interrupts are on in the main loop) */
        }
        tx_buf[tx_head] = data[i];
        tx_head = next;
        UCSR0B |= (uint8_t)(1u << UDRIE0);
    }
}

const gf_hal_t board_hal = {0, hal_read_counts, hal_read_adc, hal_set_output, hal_uart_write};

/* ------------------------------------------------------------------ main-loop API */
uint8_t board_take_tick(void)
{
    uint16_t sum[N_ADC];
    uint8_t n[N_ADC], j;
    uint8_t sreg = SREG;
    if (!tick_pending)
        return 0u;
    cli(); /* copy the latched snapshot in one piece */
    tick_pending = 0u;
    for (j = 0; j < 2u; ++j)
        snap_counts[j] = tick_counts[j];
    for (j = 0; j < N_ADC; ++j) {
        sum[j] = tick_sum[j];
        n[j] = tick_n[j];
    }
    SREG = sreg;
    for (j = 0; j < 2u; ++j) {
        snap_ma[j] = adc_mean(sum[ch_current[j]], n[ch_current[j]], current_fs_ma[j]);
        snap_mv[j] = adc_mean(sum[ch_voltage[j]], n[ch_voltage[j]], voltage_fs_mv[j]);
    }
    return 1u;
}

uint8_t board_work_pending(void)
{
    return (uint8_t)(tick_pending || estop_fired || rx_head != rx_tail);
}

uint8_t board_take_estop(void)
{
    uint8_t fired = estop_fired;
    if (fired)
        estop_fired = 0u;
    return fired;
}

uint8_t board_uart_getc(uint8_t *b)
{
    if (rx_head == rx_tail)
        return 0u;
    *b = rx_buf[rx_tail];
    rx_tail = (uint8_t)((rx_tail + 1u) & (RX_SIZE - 1u));
    return 1u;
}

uint16_t board_tick_overruns(void)
{
    uint16_t n;
    uint8_t sreg = SREG;
    cli();
    n = overruns;
    SREG = sreg;
    return n;
}

void board_init(void)
{
    const uint16_t ubrr = (uint16_t)((F_CPU + 4UL * BOARD_BAUD) / (8UL * BOARD_BAUD) - 1UL);
    /* UART 115200 8N1, double speed (2.1 % error at 16 MHz) */
    UBRR0H = (uint8_t)(ubrr >> 8);
    UBRR0L = (uint8_t)ubrr;
    UCSR0A = (uint8_t)(1u << U2X0);
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
    UCSR0B = (uint8_t)((1u << RXEN0) | (1u << TXEN0) | (1u << RXCIE0));
    /* motors: DIR outputs low, PWM 0, Timer0 phase-correct 8-bit, no prescaler */
    DDRB |= (uint8_t)((1u << DIR0_BIT) | (1u << DIR1_BIT) | (1u << BOARD_TICK_BUSY_BIT));
    PORTB &= (uint8_t)~((1u << DIR0_BIT) | (1u << DIR1_BIT) | (1u << BOARD_TICK_BUSY_BIT));
    OCR0A = 0u;
    OCR0B = 0u;
    TCCR0A = (uint8_t)((1u << COM0A1) | (1u << COM0B1) | (1u << WGM00));
    TCCR0B = (uint8_t)(1u << CS00);
    PWM_SETUP();
    /* encoders: inputs with pull-ups, pin-change interrupt */
    ENC_DDR &= (uint8_t)~((1u << ENC_A0) | (1u << ENC_B0) | (1u << ENC_A1) | (1u << ENC_B1));
    ENC_PORT |= (uint8_t)((1u << ENC_A0) | (1u << ENC_B0) | (1u << ENC_A1) | (1u << ENC_B1));
    enc_prev[0] = (uint8_t)((((ENC_PIN >> ENC_A0) & 1u) << 1) | ((ENC_PIN >> ENC_B0) & 1u));
    enc_prev[1] = (uint8_t)((((ENC_PIN >> ENC_A1) & 1u) << 1) | ((ENC_PIN >> ENC_B1) & 1u));
    PCMSK2 = (uint8_t)ENC_PCMSK_BITS;
    /* e-stop: input with pull-up, pin-change interrupt */
    DDRB &= (uint8_t)~(1u << ESTOP_BIT);
    PORTB |= (uint8_t)(1u << ESTOP_BIT);
    PCMSK0 = (uint8_t)(1u << ESTOP_PCINT);
    PCICR = (uint8_t)((1u << PCIE0) | (1u << PCIE2));
    if (!(PINB & (1u << ESTOP_BIT)))
        estop_fired = 1u; /* pressed at power-up */
    /* ADC: AVcc reference, 125 kHz (prescaler 128), interrupt-driven round robin */
    ADMUX = (uint8_t)(1u << REFS0);
    ADCSRA = (uint8_t)((1u << ADEN) | (1u << ADIE) | (1u << ADPS2) | (1u << ADPS1) |
                       (1u << ADPS0) | (1u << ADSC));
}

void board_start_tick(void)
{
    /* tick: Timer1 CTC, prescaler 8 -> 2 MHz, 15 ms = 30000 counts */
    TCCR1A = 0u;
    TCNT1 = 0u;
    OCR1A = (uint16_t)(F_CPU / 8UL / 1000UL * BOARD_TICK_US / 1000UL - 1UL);
    TCCR1B = (uint8_t)((1u << WGM12) | (1u << CS11));
    TIMSK1 = (uint8_t)(1u << OCIE1A);
}
