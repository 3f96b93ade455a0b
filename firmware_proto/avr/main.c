/* main.c: the guard robot firmware on an AVR (see board.h for the wiring).
 *
 * Everything time-critical runs in the interrupts of hal_avr.c; the main loop hands the
 * tick, the e-stop input and the received bytes to the portable core (../core/guard_fw.c).
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/wdt.h>

#include "board.h"

#define FIRMWARE_ID 0x47554331UL /* "GUC1": guard C core, AVR port */
#define RX_BYTES_PER_LOOP 16u    /* keep the tick latency short under a flood of bytes */

/* The guard robot (guardid/robots/guard.yaml): 12-slot quadrature encoders (48 counts per
   motor revolution) behind 500:1 and 1000:1 gears, 12 V supply, 8-bit PWM, tilt travel
   -10 .. +35 degrees, PID 40 V/rad, 10 V/(rad s), 1 V s/rad. */
static const gf_config_t config PROGMEM = { /* in flash: copied once by gf_init */
    2u,           /* n_joints */
    1u,           /* INFO after reset */
    BOARD_TICK_US,
    FIRMWARE_ID,
    {
        {24000u, 12000, 8u, 0u, 0, 0, 40000000L, 10000000L, 1000000L},
        {48000u, 12000, 8u, 1u, -1333, 4666, 40000000L, 10000000L, 1000000L},
    },
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
    wdt_enable(WDTO_120MS); /* a hung main loop resets the MCU: motors off, INFO sent */
    for (;;) {
        wdt_reset();
        if (board_take_estop())
            gf_estop(&fw);
        if (board_take_tick())
            gf_tick(&fw);
        for (n = 0; n < RX_BYTES_PER_LOOP && board_uart_getc(&b); ++n)
            gf_receive_byte(&fw, b);
    }
}
