/* A probe firmware for the emulated-board tests (avr-libc only, no Arduino core).
 *
 * Every 1 ms (Timer1 in CTC mode, prescaler 64, OCR1A = 249) the compare-match interrupt:
 *   - drives D22 (PA0) high for its whole duration (the busy pin),
 *   - converts analog input A<n> (n = 0, 1, 2, 0, 1, 2, ...; AVcc reference, prescaler 128) with
 *     D23 (PA1) high from the start of the conversion until ADSC clears,
 *   - sends 4 bytes on USART0: 0xA5, the channel, the 10-bit result (high byte, low byte).
 * INT4 (D2, PE4) counts rising edges; every 100th period sends 0x5A and the count (2 bytes).
 * USART0: 115200 baud requested with U2X0 = 1, so UBRR0 = 16 (BAUD = F_CPU / (8 (UBRR0 + 1))).
 */
#include <avr/io.h>
#include <avr/interrupt.h>

static volatile uint16_t edges = 0;
static uint8_t channel = 0;
static uint16_t period = 0;

static void send(uint8_t b) {
    while (!(UCSR0A & (1 << UDRE0))) {}
    UDR0 = b;
}

ISR(INT4_vect) { edges++; }

ISR(TIMER1_COMPA_vect) {
    PORTA |= (1 << PA0);
    ADMUX = (1 << REFS0) | channel;
    PORTA |= (1 << PA1);
    ADCSRA |= (1 << ADSC);
    while (ADCSRA & (1 << ADSC)) {}
    PORTA &= ~(1 << PA1);
    uint16_t v = ADC;
    send(0xA5);
    send(channel);
    send(v >> 8);
    send(v & 0xff);
    channel = (channel + 1) % 3;
    if (++period == 100) {
        period = 0;
        uint16_t e = edges;
        send(0x5A);
        send(e >> 8);
        send(e & 0xff);
    }
    PORTA &= ~(1 << PA0);
}

int main(void) {
    DDRA = (1 << PA0) | (1 << PA1);
    UCSR0A = (1 << U2X0);
    UBRR0 = 16;
    UCSR0B = (1 << TXEN0);
    UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);
    ADCSRA = (1 << ADEN) | (1 << ADPS2) | (1 << ADPS1) | (1 << ADPS0);
    EICRB = (1 << ISC41) | (1 << ISC40);          /* INT4 on rising edges */
    EIMSK = (1 << INT4);
    TCCR1A = 0;
    TCCR1B = (1 << WGM12) | (1 << CS11) | (1 << CS10);
    OCR1A = 249;
    TIMSK1 = (1 << OCIE1A);
    sei();
    for (;;) {}
}
