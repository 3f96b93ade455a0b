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
 */
#ifndef GUARD_AVR_BOARD_H
#define GUARD_AVR_BOARD_H

#include <stdint.h>

#include "guard_fw.h"

#ifndef F_CPU
#define F_CPU 16000000UL
#endif
#define BOARD_BAUD 115200UL
#define BOARD_TICK_US 15000UL

/* Analog front end: full scale (code 0 or 1023 ~ -/+ full scale) at +-512 codes. */
#define BOARD_CURRENT_FS_MA 2000L  /* +-2 A current sense */
#define BOARD_VOLTAGE_FS_MV 15000L /* +-15 V motor-voltage sense */

/* Encoder sign per joint (+1 or -1) to match the motor's positive direction. */
#define BOARD_ENC0_SIGN 1
#define BOARD_ENC1_SIGN 1

void board_init(void);
extern const gf_hal_t board_hal;
/* 1 once per elapsed tick (latches the encoder counts and the ADC means of the period). */
uint8_t board_take_tick(void);
/* 1 if the e-stop input fired since the last call (the PWM is already cut). */
uint8_t board_take_estop(void);
/* 1 and *b set when a received byte is waiting. */
uint8_t board_uart_getc(uint8_t *b);
/* Ticks the main loop was too late to process (diagnostics). */
uint16_t board_tick_overruns(void);

#endif /* GUARD_AVR_BOARD_H */
