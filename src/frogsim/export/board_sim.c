/* frogsim's emulated Arduino Mega 2560: simavr's ATmega2560 core driven in lockstep from Python.
 *
 * Built on first use by frogsim.export.emulator (gcc, linked against Debian's libsimavr) and
 * loaded with ctypes. Everything the plant and the firmware exchange passes through here:
 *   - analog inputs: the voltage of each of the 16 ADC inputs, in millivolts (simavr's unit),
 *     held until changed (board_set_adc_mv; ADC8..15 through adc_trigger, below);
 *   - digital inputs: pins driven from outside (quadrature encoders; board_set_pin);
 *   - digital outputs: every change of a watched pin, with the AVR cycle at which the firmware
 *     wrote it, kept in a queue (board_watch, board_events): valve pins and the firmware's
 *     busy pin, whose edges time its control interrupt in AVR cycles;
 *   - the serial port USART0: every byte the firmware sends, with its cycle (board_uart_read);
 *     simavr paces the bytes at the baud rate the firmware set.
 * The AVR runs only inside board_run_until, up to a given cycle count.
 */
#include <stdarg.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/avr_adc.h>
#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_interrupts.h>

#define MAX_WATCH 64
#define ADC_INPUTS 16
#define EVENT_CAP (1 << 16)
#define UART_CAP (1 << 20)
#define MAX_VALVES 32
#define MAX_ENC 16

typedef struct board_t board_t;
typedef struct { board_t *b; int index; int last; } watch_t;

struct board_t {
    avr_t *avr;
    watch_t watch[MAX_WATCH];
    int n_watch;
    /* pin events: cycle, watch index, value; a ring that board_events drains */
    uint64_t ev_cycle[EVENT_CAP];
    int32_t ev_index[EVENT_CAP];
    int32_t ev_value[EVENT_CAP];
    long ev_head, ev_tail, ev_lost;
    uint8_t uart[UART_CAP];
    uint64_t uart_cycle[UART_CAP];
    long uart_head, uart_tail, uart_lost;
    /* the analog inputs' voltages [mV]; simavr 1.6 keeps only ADC0..ADC7 (adc_values[8]) */
    uint32_t mv[ADC_INPUTS];
    avr_adc_t *adc;
    /* board_run_until_pin: stop when watch `stop_index` changes to `stop_value` */
    int stop_index, stop_value, stop_hit;
    /* cycles the core spent asleep (SLEEP instruction until the next interrupt woke it), and of
     * them those while the watch `snap_index` (board_frame's busy pin) was high: a firmware
     * that idles inside its interrupt (waiting for the ADC) sleeps there too */
    uint64_t sleep_cycles, sleep_busy_cycles;
    watch_t *busy;
    /* board_frame (snap_setup): at each fall of watch `snap_index`, `snap_len` bytes of data memory at
     * `snap_addr` are copied into the caller's buffer (the counts an interrupt read, at its end) */
    int snap_index;
    uint32_t snap_addr;
    int snap_len;
    uint8_t *snap_buf;
    long snap_n, snap_max;
    /* board_track: the pin events read into what a controller period gives (board_drain) */
    int tr_on, tr_busy, tr_tick, tr_nv;
    int tr_owner[MAX_WATCH];                 /* the valve a watch belongs to, or -1 */
    int tr_charge[MAX_VALVES], tr_dis[MAX_VALVES];
    int tr_level[MAX_WATCH];
    int8_t tr_modes[MAX_VALVES];
    int64_t *tr_cnt;                         /* TR_* below, the caller's */
    uint64_t *ch_cycle; int32_t *ch_j; int8_t *ch_mode; long ch_max;
    uint64_t *ex_start, *ex_end; int64_t *ex_write; int8_t *ex_dec; long ex_max;
    uint64_t *tk; long tk_max;
    /* board_frame_setup: what board_frame sets and runs each period */
    int fr_on, fr_nadc, fr_shift, fr_nenc, fr_snap_index, fr_snap_len;
    uint32_t fr_vref, fr_snap_addr;
    const int32_t *fr_inputs; const int64_t *fr_counts;
    char fr_a_port[MAX_ENC], fr_b_port[MAX_ENC];
    int32_t fr_a_bit[MAX_ENC], fr_b_bit[MAX_ENC];
    int32_t *fr_count; const int32_t *fr_target; long fr_most;
    uint8_t *fr_snaps; long fr_max_snaps;
};

/* board_track's counters (int64, the caller's array) */
enum { TR_CHANGES, TR_EXECUTIONS, TR_TICKS, TR_BOTH_OPEN, TR_RISE, TR_LAST_EDGE, TR_MORE, TR_SIZE };

static void pin_changed(struct avr_irq_t *irq, uint32_t value, void *param) {
    watch_t *w = (watch_t *)param;
    board_t *b = w->b;
    if (b->ev_tail - b->ev_head >= EVENT_CAP) { b->ev_lost++; return; }
    long k = b->ev_tail % EVENT_CAP;
    b->ev_cycle[k] = b->avr->cycle;
    b->ev_index[k] = w->index;
    b->ev_value[k] = (int32_t)value;
    b->ev_tail++;
    if (w->index == b->stop_index && (int)value == b->stop_value && w->last != (int)value)
        b->stop_hit = 1;
    if (w->index == b->snap_index && value == 0 && w->last != 0 && b->snap_buf) {
        if (b->snap_n < b->snap_max)
            memcpy(b->snap_buf + (size_t)b->snap_n * b->snap_len, b->avr->data + b->snap_addr, b->snap_len);
        b->snap_n++;
    }
    w->last = (int)value;
}

static void uart_out(struct avr_irq_t *irq, uint32_t value, void *param) {
    board_t *b = (board_t *)param;
    if (b->uart_tail - b->uart_head >= UART_CAP) { b->uart_lost++; return; }
    long k = b->uart_tail % UART_CAP;
    b->uart[k] = (uint8_t)value;
    b->uart_cycle[k] = b->avr->cycle;
    b->uart_tail++;
}

/* simavr's messages (the ELF loader's "Loaded N .text") go nowhere: frogsim reports itself */
static void quiet(struct avr_t *avr, const int level, const char *format, va_list ap) {
    (void)avr; (void)level; (void)format; (void)ap;
}

/* simavr's default sleep callback waits in real time for as long as the AVR sleeps (so that a
 * firmware never runs faster than the wall clock); in lockstep the plant sets the pace: a
 * sleeping AVR skips to its next event at once. simavr calls it once for each skip, then adds
 * 1 + how_long cycles: the sleep cycles are counted here (also the skip made in the step that
 * ran the SLEEP instruction), those with the busy pin high apart. */
static void no_wait(struct avr_t *avr, avr_cycle_count_t how_long) {
    board_t *b = (board_t *)avr->custom.data;
    if (!b)
        return;
    b->sleep_cycles += 1 + how_long;
    if (b->busy && b->busy->last)
        b->sleep_busy_cycles += 1 + how_long;
}

/* A cycle timer that does nothing: set at until - 1 it ends a sleeping core's skip there
 * (see run_to). */
static avr_cycle_count_t wake(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)avr; (void)when; (void)param;
    return 0;
}

/* simavr 1.6 emulates the ATmega2560's ADC with eight input slots (adc_values[8]): a conversion
 * of ADC8..ADC15 (MUX5 set) does not read the voltage given for it. The harness keeps all
 * sixteen voltages itself and, when a conversion starts (simavr raises ADC_IRQ_OUT_TRIGGER with
 * the conversion's mux), writes the selected input's voltage into a slot simavr reads: ADC8..15
 * are mapped onto slots 0..7 (their mux entries get src = n - 8 and, as the marker of the input
 * they are, diff = n), and every conversion's slot is loaded just before it is made. */
static void adc_trigger(struct avr_irq_t *irq, uint32_t value, void *param) {
    board_t *b = (board_t *)param;
    avr_adc_mux_t mux;
    memcpy(&mux, &value, sizeof(mux));
    if (mux.kind != ADC_MUX_SINGLE)
        return;
    int input = mux.diff >= 8 ? (int)mux.diff : (int)mux.src;
    if (input < 0 || input >= ADC_INPUTS || mux.src >= 8)
        return;
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + mux.src), b->mv[input]);
}

static avr_adc_t *find_adc(avr_t *avr) {
    for (avr_io_t *io = avr->io_port; io; io = io->next)
        if (io->kind && strcmp(io->kind, "adc") == 0)
            return (avr_adc_t *)io;
    return NULL;
}

/* Load an ELF for the ATmega2560 at `frequency` Hz with AVcc = AREF = `vref_mv`.
 * Returns NULL if the file cannot be read or the core cannot be made. */
board_t *board_open(const char *elf, uint32_t frequency, uint32_t vref_mv) {
    elf_firmware_t fw;
    memset(&fw, 0, sizeof(fw));
    avr_global_logger_set(quiet);
    if (elf_read_firmware(elf, &fw) != 0)
        return NULL;
    avr_t *avr = avr_make_mcu_by_name("atmega2560");
    if (!avr)
        return NULL;
    avr_init(avr);
    avr->log = 0;
    avr->sleep = no_wait;
    avr_load_firmware(avr, &fw);
    avr->frequency = frequency;
    avr->vcc = avr->avcc = avr->aref = vref_mv;
    board_t *b = (board_t *)calloc(1, sizeof(board_t));
    b->avr = avr;
    avr->custom.data = b;                              /* for no_wait (simavr calls no custom hook) */
    b->stop_index = -1;
    b->snap_index = -1;
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~AVR_UART_FLAG_STDIO;                      /* bytes go to board_uart_read only */
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), uart_out, b);
    b->adc = find_adc(avr);
    if (b->adc) {
        for (int n = 8; n < ADC_INPUTS; n++) {           /* MUX5:0 = 1 0 0 n-8: single-ended ADCn */
            avr_adc_mux_t *m = &b->adc->muxmode[32 + (n - 8)];
            m->kind = ADC_MUX_SINGLE;
            m->src = n - 8;
            m->diff = n;
        }
        avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_OUT_TRIGGER), adc_trigger, b);
    }
    return b;
}

void board_close(board_t *b) {
    if (!b) return;
    avr_terminate(b->avr);
    free(b);
}

/* Watch output pin `bit` of port `port` ('A'..'L'); its changes are queued under `index`. */
int board_watch(board_t *b, char port, int bit, int index) {
    if (b->n_watch >= MAX_WATCH) return -1;
    avr_irq_t *irq = avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
    if (!irq) return -2;
    watch_t *w = &b->watch[b->n_watch++];
    w->b = b;
    w->index = index;
    w->last = 0;                                      /* every pin is low out of reset */
    avr_irq_register_notify(irq, pin_changed, w);
    return 0;
}

void board_set_adc_mv(board_t *b, int channel, uint32_t mv) {
    if (channel < 0 || channel >= ADC_INPUTS)
        return;
    b->mv[channel] = mv;
    if (channel < 8)
        avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + channel), mv);
}

/* board_set_adc_mv for `n` inputs at once: input `inputs[i]` to `mv[i]` millivolts, each
 * raised only where it changed (a held voltage is no new event for simavr) */
void board_set_adc_many(board_t *b, int n, const int32_t *inputs, const uint32_t *mv) {
    for (int i = 0; i < n; i++) {
        int ch = inputs[i];
        if (ch >= 0 && ch < ADC_INPUTS && b->mv[ch] != mv[i])
            board_set_adc_mv(b, ch, mv[i]);
    }
}

/* The analog inputs from ADC counts: input `inputs[i]` to the smallest whole millivolts simavr's
 * converter reads as count `counts[i]` << `shift` (of 1023 over `vref_mv`): ceil(c vref / 1023),
 * as frogsim.export.emulator.millivolts_for_count. Returns -1, or the first i whose count is
 * outside 0..1023 >> shift (nothing is set then). */
long board_set_adc_counts(board_t *b, int n, const int32_t *inputs, const int64_t *counts, int shift,
                          uint32_t vref_mv) {
    for (int i = 0; i < n; i++)
        if (counts[i] < 0 || (counts[i] << shift) > 1023)
            return i;
    for (int i = 0; i < n; i++) {
        int ch = inputs[i];
        uint64_t c = (uint64_t)(counts[i] << shift);
        uint32_t mv = (uint32_t)((c * vref_mv + 1022) / 1023);
        if (ch >= 0 && ch < ADC_INPUTS && b->mv[ch] != mv)
            board_set_adc_mv(b, ch, mv);
    }
    return -1;
}

int board_set_pin(board_t *b, char port, int bit, int value) {
    avr_irq_t *irq = avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
    if (!irq) return -2;
    avr_raise_irq(irq, value ? 1 : 0);
    return 0;
}

/* Watch interrupt vector `vector` (the datasheet's vector number, 1 = INT0; TIMER1_COMPA is 17 on
 * the ATmega2560): its flag being raised (the hardware event, e.g. Timer1's compare match) is
 * queued as an event of value 1 under `index`, its being taken by the CPU as value 0. A raise
 * while the flag is still set is no new event (the hardware sets the flag once: the later
 * event is lost, as on the chip). */
int board_watch_vector(board_t *b, int vector, int index) {
    if (b->n_watch >= MAX_WATCH) return -1;
    avr_irq_t *irq = avr_get_interrupt_irq(b->avr, (uint8_t)vector);
    if (!irq) return -2;
    watch_t *w = &b->watch[b->n_watch++];
    w->b = b;
    w->index = index;
    w->last = 0;
    avr_irq_register_notify(irq + AVR_INT_IRQ_PENDING, pin_changed, w);
    return 0;
}

/* Run the core until its cycle counter reaches `until`, exactly: a sleeping core skips to its
 * next event (a timer, a conversion's end), which may lie past `until` (an input's time, a
 * frame's end); a no-op cycle timer at until - 1 ends the skip at `until` (simavr adds
 * 1 + the skip). Returns 0, or -1 if the firmware stopped (returned from main with interrupts
 * off, or crashed). */
static int run_to(board_t *b, uint64_t until) {
    if (b->avr->cycle + 1 < until)
        avr_cycle_timer_register(b->avr, until - 1 - b->avr->cycle, wake, b);
    int st = cpu_Running;
    while (b->avr->cycle < until) {
        st = avr_run(b->avr);
        if (st == cpu_Done || st == cpu_Crashed)
            break;
    }
    avr_cycle_timer_cancel(b->avr, wake, b);
    return (st == cpu_Done || st == cpu_Crashed) ? -1 : 0;
}

uint64_t board_sleep_cycles(board_t *b) { return b->sleep_cycles; }
uint64_t board_sleep_busy_cycles(board_t *b) { return b->sleep_busy_cycles; }

/* Run the core until its cycle counter reaches `cycle`. Returns 0, or -1 if the firmware
 * stopped (returned from main with interrupts off, or crashed). */
int board_run_until(board_t *b, uint64_t cycle) {
    return run_to(b, cycle);
}

/* Run until watched pin `index` changes (from the other level) to `value` (the change is queued as an event) or the
 * cycle counter reaches `max_cycle`. Returns 1 if the pin changed, 0 if the cycle limit came
 * first, -1 if the firmware stopped or crashed. */
int board_run_until_pin(board_t *b, int index, int value, uint64_t max_cycle) {
    b->stop_index = index;
    b->stop_value = value;
    b->stop_hit = 0;
    if (b->avr->cycle + 1 < max_cycle)
        avr_cycle_timer_register(b->avr, max_cycle - 1 - b->avr->cycle, wake, b);
    int st = cpu_Running;
    while (!b->stop_hit && b->avr->cycle < max_cycle) {
        st = avr_run(b->avr);
        if (st == cpu_Done || st == cpu_Crashed)
            break;
    }
    avr_cycle_timer_cancel(b->avr, wake, b);
    b->stop_index = -1;
    return (st == cpu_Done || st == cpu_Crashed) ? -1 : b->stop_hit;
}

/* At each fall of watch `snap_index` (the busy pin) while a period runs, `snap_len` bytes of data
 * memory at `snap_addr` are copied into `snaps` (at most `max_snaps`; pin_changed). Returns 0, or
 * -1 for a range outside the data memory. */
static int snap_setup(board_t *b, int snap_index, uint32_t snap_addr, int snap_len, uint8_t *snaps,
                      long max_snaps) {
    if (snap_len < 0 || (uint64_t)snap_addr + (uint64_t)snap_len > (uint64_t)b->avr->ramend + 1)
        return -1;
    b->snap_index = snap_index;
    b->busy = NULL;
    for (int w = 0; w < b->n_watch; w++)
        if (b->watch[w].index == snap_index)
            b->busy = &b->watch[w];
    b->snap_addr = snap_addr;
    b->snap_len = snap_len;
    b->snap_buf = snaps;
    b->snap_n = 0;
    b->snap_max = max_snaps;
    return 0;
}

/* Run from `start` to `end` (one controller period) with `n_enc` quadrature encoders moving,
 * taking snapshots at the busy pin's falls (snap_setup): encoder e goes
 * from count[e] to target[e] (count[] is updated; more than `most` counts away: -2 - e is
 * returned before anything runs), one edge per count, spread evenly over the
 * period: the m-th (m = 1..|n|) at start + round(m (end - start) / (|n| + 1)) (ties to even, as
 * Python's round). At each edge, B is set first (to A's new level counting up, to its opposite
 * counting down), then A to the count's parity; edges of several encoders at one cycle go in
 * encoder order. Returns the number of falls (snapshots wanted; more than max_snaps: some were not
 * kept), or -1 if the firmware stopped or crashed. */
long board_run_frame_enc(board_t *b, uint64_t start, uint64_t end, int n_enc, const char *a_port,
                         const int32_t *a_bit, const char *b_port, const int32_t *b_bit, int32_t *count,
                         const int32_t *target, long most, int snap_index, uint32_t snap_addr, int snap_len,
                         uint8_t *snaps, long max_snaps) {
    if (n_enc < 0 || n_enc > MAX_ENC)
        return -1;
    for (int e = 0; e < n_enc; e++) {            /* more than `most` counts: refused, nothing run */
        long n = (long)target[e] - (long)count[e];
        if (n > most || -n > most)
            return -2 - e;
    }
    if (snap_setup(b, snap_index, snap_addr, snap_len, snaps, max_snaps) != 0)
        return -1;
    long done[MAX_ENC], total[MAX_ENC];
    double spacing[MAX_ENC];
    avr_irq_t *irq_a[MAX_ENC], *irq_b[MAX_ENC];
    double period = (double)(end - start);
    for (int e = 0; e < n_enc; e++) {
        long n = (long)target[e] - (long)count[e];
        total[e] = n < 0 ? -n : n;
        done[e] = 0;
        spacing[e] = period / (double)(total[e] + 1);
        irq_a[e] = avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ(a_port[e]), a_bit[e]);
        irq_b[e] = avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ(b_port[e]), b_bit[e]);
        if (total[e] && (!irq_a[e] || !irq_b[e])) {
            b->snap_buf = NULL;
            return -1;
        }
    }
    for (;;) {
        int next = -1;
        uint64_t at = end;
        for (int e = 0; e < n_enc; e++) {
            if (done[e] >= total[e])
                continue;
            uint64_t c = start + (uint64_t)nearbyint((double)(done[e] + 1) * spacing[e]);
            if (next < 0 || c < at) {
                next = e;
                at = c;
            }
        }
        if (next < 0)
            break;
        if (run_to(b, at) != 0) {
            b->snap_buf = NULL;
            return -1;
        }
        int up = target[next] > count[next];
        count[next] += up ? 1 : -1;
        int level = count[next] & 1;
        avr_raise_irq(irq_b[next], up ? level : 1 - level);
        avr_raise_irq(irq_a[next], level);
        done[next]++;
    }
    int st = run_to(b, end);
    b->snap_buf = NULL;
    return st != 0 ? -1 : b->snap_n;
}

uint64_t board_cycle(board_t *b) { return b->avr->cycle; }

/* Copy `n` bytes of data memory from address `addr` (the data space: 0 = R0, 0x200 the first
 * SRAM byte on the ATmega2560) into `out`; returns n, or -1 if the range is outside it. */
long board_read_ram(board_t *b, uint32_t addr, uint8_t *out, long n) {
    if (addr + (uint64_t)n > (uint64_t)b->avr->ramend + 1)
        return -1;
    memcpy(out, b->avr->data + addr, (size_t)n);
    return n;
}

/* Move up to `max` queued pin events into the arrays; returns how many. */
long board_events(board_t *b, uint64_t *cycle, int32_t *index, int32_t *value, long max) {
    long n = 0;
    while (b->ev_head < b->ev_tail && n < max) {
        long k = b->ev_head % EVENT_CAP;
        cycle[n] = b->ev_cycle[k];
        index[n] = b->ev_index[k];
        value[n] = b->ev_value[k];
        b->ev_head++;
        n++;
    }
    return n;
}

/* Move up to `max` bytes the firmware sent on USART0 (and their cycles); returns how many. */
long board_uart_read(board_t *b, uint8_t *out, uint64_t *cycle, long max) {
    long n = 0;
    while (b->uart_head < b->uart_tail && n < max) {
        long k = b->uart_head % UART_CAP;
        out[n] = b->uart[k];
        cycle[n] = b->uart_cycle[k];
        b->uart_head++;
        n++;
    }
    return n;
}

long board_lost(board_t *b) { return b->ev_lost + b->uart_lost; }

/* --- a controller period in one call ---------------------------------------------------------
 * frogsim.export.sil.BoardRun reads the queued pin events into the period's valve mode changes,
 * the control interrupt's executions and Timer1's compare matches (board_drain); board_frame
 * sets the analog inputs, runs the period with its encoder edges (board_run_frame_enc) and
 * drains, all in one call, with the arrays registered once (board_track, board_frame_setup). */

/* Track watch `busy` (the firmware's busy pin: an execution from its rise to its fall), watch
 * `tick` (Timer1's compare flag: a match at each raise) and `nv` valves (valve j's charge pin is
 * watch charge[j], its discharge pin watch dis[j]; mode 1 charge alone open, -1 discharge alone,
 * 0 otherwise). board_drain writes into the caller's arrays: the mode changes (cycle, valve, mode;
 * at most ch_max), the executions that ended (start, end, the cycle of the execution's last valve
 * change or -1, the valves' modes at its end as row k of ex_dec (ex_max rows of nv); at most
 * ex_max), the compare matches' cycles (at most tk_max), and the counters cnt[TR_SIZE].
 * Returns 0, or -1 for an index out of range. */
int board_track(board_t *b, int busy, int tick, int nv, const int32_t *charge, const int32_t *dis, int64_t *cnt,
                uint64_t *ch_cycle, int32_t *ch_j, int8_t *ch_mode, long ch_max, uint64_t *ex_start,
                uint64_t *ex_end, int64_t *ex_write, int8_t *ex_dec, long ex_max, uint64_t *tk, long tk_max) {
    if (nv < 0 || nv > MAX_VALVES || busy < 0 || busy >= MAX_WATCH || tick < -1 || tick >= MAX_WATCH)
        return -1;
    for (int w = 0; w < MAX_WATCH; w++) {
        b->tr_owner[w] = -1;
        b->tr_level[w] = 0;
    }
    for (int j = 0; j < nv; j++) {
        if (charge[j] < 0 || charge[j] >= MAX_WATCH || dis[j] < 0 || dis[j] >= MAX_WATCH)
            return -1;
        b->tr_charge[j] = charge[j];
        b->tr_dis[j] = dis[j];
        b->tr_owner[charge[j]] = j;
        b->tr_owner[dis[j]] = j;
        b->tr_modes[j] = 0;
    }
    b->tr_busy = busy;
    b->tr_tick = tick;
    b->tr_nv = nv;
    b->tr_cnt = cnt;
    for (int k = 0; k < TR_SIZE; k++)
        cnt[k] = 0;
    cnt[TR_RISE] = -1;
    cnt[TR_LAST_EDGE] = -1;
    b->ch_cycle = ch_cycle; b->ch_j = ch_j; b->ch_mode = ch_mode; b->ch_max = ch_max;
    b->ex_start = ex_start; b->ex_end = ex_end; b->ex_write = ex_write; b->ex_dec = ex_dec; b->ex_max = ex_max;
    b->tk = tk; b->tk_max = tk_max;
    b->tr_on = 1;
    return 0;
}

/* Read the queued pin events, in order, into board_track's arrays (their counts start at 0 at
 * each call). An event that would overfill an array stays queued for the next call:
 * cnt[TR_MORE] is 1 then. Returns -1 without board_track, else cnt[TR_MORE]. */
long board_drain(board_t *b) {
    if (!b->tr_on)
        return -1;
    int64_t *cnt = b->tr_cnt;
    cnt[TR_CHANGES] = cnt[TR_EXECUTIONS] = cnt[TR_TICKS] = 0;
    cnt[TR_MORE] = 0;
    while (b->ev_head < b->ev_tail) {
        long k = b->ev_head % EVENT_CAP;
        uint64_t c = b->ev_cycle[k];
        int i = b->ev_index[k];
        int v = b->ev_value[k];
        if (i < 0 || i >= MAX_WATCH) {                      /* not a tracked watch */
            b->ev_head++;
            continue;
        }
        if (i == b->tr_busy) {
            if (!v && cnt[TR_RISE] >= 0 && cnt[TR_EXECUTIONS] >= b->ex_max) {
                cnt[TR_MORE] = 1;
                break;
            }
            b->tr_level[i] = v;
            if (v) {
                cnt[TR_RISE] = (int64_t)c;
            } else if (cnt[TR_RISE] >= 0) {
                long e = cnt[TR_EXECUTIONS]++;
                b->ex_start[e] = (uint64_t)cnt[TR_RISE];
                b->ex_end[e] = c;
                memcpy(b->ex_dec + e * b->tr_nv, b->tr_modes, (size_t)b->tr_nv);
                b->ex_write[e] = (cnt[TR_LAST_EDGE] >= 0 && cnt[TR_LAST_EDGE] >= cnt[TR_RISE]) ? cnt[TR_LAST_EDGE] : -1;
                cnt[TR_RISE] = -1;
            }
        } else if (i == b->tr_tick) {
            if (v && cnt[TR_TICKS] >= b->tk_max) {
                cnt[TR_MORE] = 1;
                break;
            }
            b->tr_level[i] = v;
            if (v)
                b->tk[cnt[TR_TICKS]++] = c;
        } else {
            int j = b->tr_owner[i];
            if (j < 0) {
                b->tr_level[i] = v;
                b->ev_head++;
                continue;
            }
            int old = b->tr_level[i];
            b->tr_level[i] = v;
            int ch = b->tr_level[b->tr_charge[j]], dis = b->tr_level[b->tr_dis[j]];
            int mode = (ch && !dis) ? 1 : ((dis && !ch) ? -1 : 0);
            if (mode != b->tr_modes[j] && cnt[TR_CHANGES] >= b->ch_max) {
                b->tr_level[i] = old;                    /* read again at the next call */
                cnt[TR_MORE] = 1;
                break;
            }
            if (ch && dis)
                cnt[TR_BOTH_OPEN]++;
            if (mode != b->tr_modes[j]) {
                long n = cnt[TR_CHANGES]++;
                b->tr_modes[j] = (int8_t)mode;
                cnt[TR_LAST_EDGE] = (int64_t)c;
                b->ch_cycle[n] = c;
                b->ch_j[n] = j;
                b->ch_mode[n] = (int8_t)mode;
            }
        }
        b->ev_head++;
    }
    return cnt[TR_MORE];
}

/* What board_frame does each period: the `n_adc` analog inputs `inputs` read counts[i] << shift
 * (board_set_adc_counts, over `vref_mv`); the `n_enc` encoders (A at a_port/a_bit, B at
 * b_port/b_bit) move from count[] to target[] (board_run_frame_enc, at most `most` counts);
 * at each fall of watch `snap_index`, `snap_len` bytes at `snap_addr` go into `snaps` (at most
 * `max_snaps`). The arrays are the caller's, read at each board_frame. Returns 0, or -1. */
int board_frame_setup(board_t *b, int n_adc, const int32_t *inputs, const int64_t *counts, int shift,
                      uint32_t vref_mv, int n_enc, const char *a_port, const int32_t *a_bit, const char *b_port,
                      const int32_t *b_bit, int32_t *count, const int32_t *target, long most, int snap_index,
                      uint32_t snap_addr, int snap_len, uint8_t *snaps, long max_snaps) {
    if (n_adc < 0 || n_adc > ADC_INPUTS || n_enc < 0 || n_enc > MAX_ENC)
        return -1;
    b->fr_nadc = n_adc; b->fr_inputs = inputs; b->fr_counts = counts; b->fr_shift = shift; b->fr_vref = vref_mv;
    b->fr_nenc = n_enc;
    for (int e = 0; e < n_enc; e++) {
        b->fr_a_port[e] = a_port[e]; b->fr_a_bit[e] = a_bit[e];
        b->fr_b_port[e] = b_port[e]; b->fr_b_bit[e] = b_bit[e];
    }
    b->fr_count = count; b->fr_target = target; b->fr_most = most;
    b->fr_snap_index = snap_index; b->fr_snap_addr = snap_addr; b->fr_snap_len = snap_len;
    b->fr_snaps = snaps; b->fr_max_snaps = max_snaps;
    b->fr_on = 1;
    return 0;
}

/* One controller period from cycle `start` to `end` as board_frame_setup says, then
 * board_drain. Returns the number of falls of the snap watch (as board_run_frame_enc); -1 if the
 * firmware stopped or crashed; -2 - e if encoder e would move more than `most` counts; -1000 - i
 * if analog count i is outside the converter's range (nothing is run in these two cases); -3
 * without board_frame_setup or board_track. */
long board_frame(board_t *b, uint64_t start, uint64_t end) {
    if (!b->fr_on || !b->tr_on)
        return -3;
    long bad = board_set_adc_counts(b, b->fr_nadc, b->fr_inputs, b->fr_counts, b->fr_shift, b->fr_vref);
    if (bad >= 0)
        return -1000 - bad;
    long got = board_run_frame_enc(b, start, end, b->fr_nenc, b->fr_a_port, b->fr_a_bit, b->fr_b_port,
                                   b->fr_b_bit, b->fr_count, b->fr_target, b->fr_most, b->fr_snap_index,
                                   b->fr_snap_addr, b->fr_snap_len, b->fr_snaps, b->fr_max_snaps);
    if (got < 0)
        return got;
    board_drain(b);
    return got;
}
