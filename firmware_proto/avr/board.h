/* board.h: pin map and analog scaling of the AVR example port (ATmega2560 / Arduino Mega,
 * ATmega328P / Arduino Uno-Nano class), 16 MHz, two joints.
 *
 * Per joint: an H-bridge with PWM + DIR inputs, a quadrature encoder (A/B, pin-change
 * interrupts, 4x decoding), a current-sense amplifier and a motor-voltage sense amplifier
 * centred at mid-scale of the 10-bit ADC (code 512 = 0). One active-low e-stop input.
 *
 *                      ATmega328P            ATmega2560 (Mega pin)
 *   UART 115200 8N1    PD0 RXD / PD1 TXD     PE0 RXD0 / PE1 TXD0 (USB)
 *   PWM joint 0 / 1    PD6 OC0A / PD5 OC0B   PB7 OC0A (13) / PG5 OC0B (4)
 *   DIR joint 0 / 1    PB0 / PB1             PB0 (53) / PB1 (52)
 *   encoder 0 A / B    PD2 / PD3             PK0 (A8) / PK1 (A9)
 *   encoder 1 A / B    PD4 / PD7             PK2 (A10) / PK3 (A11)
 *   e-stop (low = stop) PB2                  PB4 (10)
 *   ADC ch 0..3        PC0..PC3              PF0..PF3 (A0..A3): I0, I1, V0, V1
 *   tick busy (out)    PB3                   PB6 (12)   high while gf_tick runs (scope/sim)
 *
 * The robot's numbers (joints, tick, counts per revolution, limits, gains, sensor full
 * scales) come from robot_config.h, generated from the robot YAML by gen_robot.py.
 */
#ifndef GUARD_AVR_BOARD_H
#define GUARD_AVR_BOARD_H

#include <avr/io.h>
#include <stdint.h>

#include "guard_fw.h"
#ifdef ROBOT_CONFIG_HEADER /* make ROBOT_CONFIG=path: a header generated for another robot */
#include ROBOT_CONFIG_HEADER
#else
#include "robot_config.h"
#endif

#ifndef F_CPU
#define F_CPU 16000000UL
#endif
#define BOARD_BAUD 115200UL
#define BOARD_TICK_US ROBOT_TICK_US
#if BOARD_TICK_US < 1000UL || BOARD_TICK_US > 32000UL
#error "board: Timer1 (prescaler 8, 16 bit) ticks 1 .. 32 ms"
#endif

/* Analog front end per joint: full scale (code 0 or 1023 ~ -/+ full scale) at +-512 codes
   (robot YAML current_sensor.range, voltage_sensor.range). */
#define BOARD_CURRENT_FS_MA ROBOT_CURRENT_FS_MA
#define BOARD_VOLTAGE_FS_MV ROBOT_VOLTAGE_FS_MV

/* ADC channel of each joint's current and motor-voltage sense (the table above). */
#ifndef BOARD_ADC_CH_CURRENT0
#define BOARD_ADC_CH_CURRENT0 0u
#endif
#ifndef BOARD_ADC_CH_CURRENT1
#define BOARD_ADC_CH_CURRENT1 1u
#endif
#ifndef BOARD_ADC_CH_VOLTAGE0
#define BOARD_ADC_CH_VOLTAGE0 2u
#endif
#ifndef BOARD_ADC_CH_VOLTAGE1
#define BOARD_ADC_CH_VOLTAGE1 3u
#endif

/* Encoder sign per joint (+1 or -1) to match the motor's positive direction. */
#ifndef BOARD_ENC0_SIGN
#define BOARD_ENC0_SIGN 1
#endif
#ifndef BOARD_ENC1_SIGN
#define BOARD_ENC1_SIGN 1
#endif

/* Instrumentation output: high while the tick's work runs (1) / low (0). */
#if defined(__AVR_ATmega2560__)
#define BOARD_TICK_BUSY_BIT 6
#else
#define BOARD_TICK_BUSY_BIT 3
#endif
#define BOARD_TICK_BUSY(on)                                                                   \
    do {                                                                                      \
        if (on)                                                                               \
            PORTB |= (uint8_t)(1u << BOARD_TICK_BUSY_BIT);                                    \
        else                                                                                  \
            PORTB &= (uint8_t)~(1u << BOARD_TICK_BUSY_BIT);                                   \
    } while (0)

void board_init(void);
/* Start the tick (Timer1): after gf_init, whose gain arithmetic takes longer than a tick. */
void board_start_tick(void);
extern const gf_hal_t board_hal;
/* 1 once per elapsed tick (latches the encoder counts and the ADC means of the period). */
uint8_t board_take_tick(void);
/* 1 if the e-stop input fired since the last call (the PWM is already cut). */
uint8_t board_take_estop(void);
/* 1 and *b set when a received byte is waiting. */
uint8_t board_uart_getc(uint8_t *b);
/* 1 if a tick, the e-stop or a received byte waits for the main loop (call with
   interrupts off before sleeping). */
uint8_t board_work_pending(void);
/* Ticks the main loop was too late to process (diagnostics). */
uint16_t board_tick_overruns(void);

#endif /* GUARD_AVR_BOARD_H */
