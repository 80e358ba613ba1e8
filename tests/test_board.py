"""The Mega 2560's facts and the ATmega2560's ADC timing against the datasheet's numbers."""
import pytest
from avr_tools import need_avr_tools

from frogsim.export import board


def test_conversion_times_are_the_datasheets():
    # Table 26-1: 13 ADC clocks a conversion, 25 for the first; Arduino's default prescaler 128
    # gives a 125 kHz ADC clock: 104 us (the figure behind "eighteen channels do not fit in 1 ms")
    assert board.conversion_time(128) == pytest.approx(104e-6)
    assert board.conversion_time(128, first=True) == pytest.approx(200e-6)
    assert board.conversion_time(16) == pytest.approx(13e-6)


@pytest.mark.parametrize("prescaler, bits", [(128, 10), (64, 8), (32, 8), (16, 8)])
def test_resolution_follows_the_adc_clock(prescaler, bits):
    # 10 bits specified from 50 to 200 kHz; 8 bits expected up to 1 MHz
    assert board.adc_bits(prescaler) == bits


def test_above_one_megahertz_is_refused():
    with pytest.raises(ValueError, match="1 MHz"):
        board.adc_bits(8)


def test_twelve_pressures_at_1_khz_need_a_faster_adc_clock():
    # 12 x 104 us = 1.25 ms > 1 ms
    # 12 x 13 x 64 / 16 MHz = 624 us is more than 60 % of 1 ms: prescaler 32 (500 kHz, 26 us)
    plan = board.plan_adc(12, 1e-3)
    assert plan.prescaler == 32 and plan.bits == 8
    assert plan.total_s <= 0.6e-3
    assert plan.channels * board.conversion_time(plan.prescaler) == pytest.approx(plan.total_s)
    assert "us" in plan.describe()


def test_one_channel_at_1_khz_keeps_full_resolution():
    plan = board.plan_adc(1, 1e-3)
    assert plan.prescaler == 128 and plan.bits == 10


def test_what_does_not_fit_is_refused_with_the_arithmetic():
    with pytest.raises(ValueError, match=r"13\.0 us"):
        board.plan_adc(16, 100e-6)           # 16 x 13 us = 208 us > 60 us of a 10 kHz period
    with pytest.raises(ValueError, match="16 analog inputs"):
        board.plan_adc(18, 1e-3)


def test_pin_map_is_the_arduino_cores():
    """Spot checks against the Mega 2560 Rev3 schematic: D13 is PB7 (the LED), D22 is PA0,
    D2 is PE4 (INT4), A0 = D54 is PF0, A8 = D62 is PK0."""
    need_avr_tools()
    pins = board.pin_map()
    assert len(pins) == board.DIGITAL_PINS
    for number, port, bit in ((13, "B", 7), (22, "A", 0), (2, "E", 4), (54, "F", 0), (62, "K", 0), (0, "E", 0)):
        assert (pins[number].port, pins[number].bit) == (port, bit)
    assert len({(p.port, p.bit) for p in pins.values()}) == board.DIGITAL_PINS
