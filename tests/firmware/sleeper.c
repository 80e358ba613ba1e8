/* A probe firmware that sleeps between interrupts (avr-libc only, no Arduino core), for the
 * emulated board's sleep tests.
 *
 * Timer1 in CTC mode without prescaler: the compare-match interrupt every OCR1A + 1 cycles
 * (OCR1A from -DPERIOD_CYCLES, default 4000) drives D22 (PA0) high, does a fixed amount of work
 * and drives it low. INT4 (D2, PE4) on rising edges drives D23 (PA1) high and low again. Between
 * interrupts the core sleeps in idle mode: nothing else runs.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#ifndef PERIOD_CYCLES
#define PERIOD_CYCLES 4000
#endif

static volatile uint8_t work;

ISR(TIMER1_COMPA_vect) {
    PORTA |= (1 << PA0);
    for (uint8_t i = 0; i < 20; i++) work++;
    PORTA &= ~(1 << PA0);
}

ISR(INT4_vect) {
    PORTA |= (1 << PA1);
    PORTA &= ~(1 << PA1);
}

int main(void) {
    DDRA = (1 << PA0) | (1 << PA1);
    EICRB = (1 << ISC41) | (1 << ISC40);          /* INT4 on rising edges */
    EIMSK = (1 << INT4);
    TCCR1A = 0;
    OCR1A = PERIOD_CYCLES - 1;
    TIMSK1 = (1 << OCIE1A);
    TCCR1B = (1 << WGM12) | (1 << CS10);          /* CTC, no prescaler */
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei();
    for (;;) {
        sleep_enable();
        sleep_cpu();
        sleep_disable();
    }
}
