"""The live reading text shared by the dashboard and the script-mode progress."""

from campaign.measure.live import live_text
from protocols.hardware import Reading


def reading(position, ok=True, pct=None):
    return Reading(time_s=0.0, position=position, signal_ok=ok, signal_pct=pct)


def test_near_the_target_the_deviation_in_micrometres():
    assert live_text(reading(300.0012), 300.0, "mm") == "reading 300.0012 mm, deviation +1.20 µm"


def test_while_moving_the_distance_to_the_target_not_a_huge_deviation():
    text = live_text(reading(241.4444), 300.0, "mm")
    assert text == "reading 241.4444 mm, +58.556 mm to the target" and "µm" not in text


def test_rotary_in_arcsec_and_the_signal():
    assert live_text(reading(90.001, pct=87), 90.0, "deg") == "reading 90.0010 deg, deviation +3.60 arcsec, signal 87 %"


def test_beam_lost_shows_no_number():
    text = live_text(reading(12.5, ok=False, pct=3), 10.0, "mm")
    assert "BEAM LOST" in text and "12.5" not in text and "signal 3 %" in text
