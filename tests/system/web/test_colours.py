"""The colour measures the palette and accessibility tests rely on (tests/system/web/colours.py): CIEDE2000
against the test data of Sharma, Wu and Dalal (2005, Table 1), WCAG 2's contrast ratio against
known pairs."""
import pytest

from .colours import ciede2000, contrast


@pytest.mark.parametrize("lab1, lab2, expected", [
    ((50.0, 2.6772, -79.7751), (50.0, 0.0, -82.7485), 2.0425),
    ((50.0, 0.0, 0.0), (50.0, -1.0, 2.0), 2.3669),
    ((50.0, 2.5, 0.0), (50.0, 0.0, -2.5), 4.3065),
    ((50.0, 2.5, 0.0), (73.0, 25.0, -18.0), 27.1492),
    ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    ((2.0776, 0.0795, -1.1350), (0.9033, -0.0636, -0.5514), 0.9082),
])
def test_ciede2000_matches_the_published_pairs(lab1, lab2, expected):
    assert ciede2000(lab1, lab2) == pytest.approx(expected, abs=5e-5)


@pytest.mark.parametrize("color1, color2, expected", [
    ((255, 255, 255), (0, 0, 0), 21.0),
    ((0x76, 0x76, 0x76), (255, 255, 255), 4.54),  # the lightest grey for body text on white (WebAIM)
    ((0x77, 0x77, 0x77), (255, 255, 255), 4.48),
    ((0xB9, 0xB9, 0xB9), (0xB9, 0xB9, 0xB9), 1.0),
])
def test_contrast_matches_wcag(color1, color2, expected):
    assert contrast(color1, color2) == pytest.approx(expected, abs=0.005)
    assert contrast(color2, color1) == pytest.approx(expected, abs=0.005)
