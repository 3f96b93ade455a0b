/* main.c: the guard robot firmware on an AVR (see board.h for the wiring).
 *
 * Everything time-critical runs in the interrupts of hal_avr.c; the main loop hands the
 * tick, the e-stop input and the received bytes to the portable core (../core/guard_fw.c).
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>
#include <avr/wdt.h>

#include "board.h"

#ifndef FIRMWARE_ID /* guardid flash passes the build's own id */
#define FIRMWARE_ID 0x47554331UL /* "GUC1": guard C core, AVR port */
#endif
#define RX_BYTES_PER_LOOP 16u    /* keep the tick latency short under a flood of bytes */

/* The robot (joints, encoder counts per revolution, supply, limits, PID gains) comes from
   its YAML through robot_config.h (generated: python firmware_proto/avr/gen_robot.py). */
static const gf_config_t config PROGMEM = { /* in flash: copied once by gf_init */
    (uint8_t)ROBOT_N_JOINTS,
    1u, /* INFO after reset */
    BOARD_TICK_US,
    FIRMWARE_ID,
    ROBOT_JOINT_CONFIG,
};

static gf_fw_t fw;

int main(void)
{
    uint8_t b, n;
    gf_config_t cfg;
    MCUSR = 0u;
    wdt_disable();
    board_init();
    sei();
    memcpy_P(&cfg, &config, sizeof cfg);
    if (gf_init(&fw, &cfg, &board_hal) != GF_OK) {
        for (;;) {
            /* bad configuration: motors stay off (board_init set PWM 0) */
        }
    }
    board_start_tick(); /* now: gf_init's 128-bit gain arithmetic takes over 15 ms */
    set_sleep_mode(SLEEP_MODE_IDLE); /* timers, ADC and UART keep running */
    wdt_enable(WDTO_120MS); /* a hung main loop resets the MCU: motors off, INFO sent */
    for (;;) {
        wdt_reset();
        if (board_take_estop())
            gf_estop(&fw);
        if (board_take_tick()) {
            BOARD_TICK_BUSY(1); /* instrumentation pin: high while the tick's work runs */
            gf_tick(&fw);
            BOARD_TICK_BUSY(0);
        }
        for (n = 0; n < RX_BYTES_PER_LOOP && board_uart_getc(&b); ++n)
            gf_receive_byte(&fw, b);
        cli(); /* nothing to do: idle until an interrupt (ADC every 104 us at the latest) */
        if (!board_work_pending()) {
            sleep_enable();
            sei(); /* the instruction after sei runs before any interrupt: no lost wake-up */
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
}
