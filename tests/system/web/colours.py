"""How different two colours look, and how they contrast. CIEDE2000 (Sharma, Wu and Dalal,
"The CIEDE2000 color-difference formula", 2005) between sRGB colours, also as seen with
protanopia or deuteranopia (Machado, Oliveira
and Fernandes, "A physiologically-based model for simulation of color vision deficiency", 2009,
severity 1: the two common red-green deficiencies); WCAG 2's contrast ratio of relative luminances
(what its contrast criteria 1.4.3 and 1.4.11 measure)."""
from __future__ import annotations

import numpy as np

D65_WHITE = np.array([0.95047, 1.0, 1.08883])
SRGB_TO_XYZ = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
# Machado et al. 2009, Table 1, severity 1.0; they act on linear RGB.
DEFICIENCIES = {
    "protanopia": np.array([[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                            [-0.003882, -0.048116, 1.051998]]),
    "deuteranopia": np.array([[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                              [-0.011820, 0.042940, 0.968881]]),
}


def hex_rgb(color: str) -> tuple[int, int, int]:
    return tuple(int(color.lstrip("#")[k:k + 2], 16) for k in (0, 2, 4))


def linear(rgb) -> np.ndarray:
    c = np.asarray(rgb, dtype=float) / 255
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lab(linear_rgb: np.ndarray) -> np.ndarray:
    xyz = SRGB_TO_XYZ @ np.clip(linear_rgb, 0, 1) / D65_WHITE
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def delta_e(rgb1, rgb2, deficiency: str | None = None) -> float:
    """CIEDE2000 between two sRGB colours (0-255), as seen with `deficiency` if given."""
    seen = (lambda c: DEFICIENCIES[deficiency] @ c) if deficiency else (lambda c: c)
    return ciede2000(lab(seen(linear(rgb1))), lab(seen(linear(rgb2))))


def ciede2000(lab1, lab2) -> float:
    (l1, a1, b1), (l2, a2, b2) = lab1, lab2
    c_mean = (np.hypot(a1, b1) + np.hypot(a2, b2)) / 2
    g = 0.5 * (1 - np.sqrt(c_mean**7 / (c_mean**7 + 25**7)))
    a1, a2 = (1 + g) * a1, (1 + g) * a2
    c1, c2 = np.hypot(a1, b1), np.hypot(a2, b2)
    h1, h2 = np.degrees(np.arctan2(b1, a1)) % 360, np.degrees(np.arctan2(b2, a2)) % 360
    dh = 0.0 if c1 * c2 == 0 else (h2 - h1 + 180) % 360 - 180
    d_hue = 2 * np.sqrt(c1 * c2) * np.sin(np.radians(dh / 2))
    l_mean, c_mean = (l1 + l2) / 2, (c1 + c2) / 2
    h_mean = h1 + h2 if c1 * c2 == 0 else ((h1 + h2) / 2 + (180 if abs(h1 - h2) > 180 else 0)) % 360
    t = (1 - 0.17 * np.cos(np.radians(h_mean - 30)) + 0.24 * np.cos(np.radians(2 * h_mean))
         + 0.32 * np.cos(np.radians(3 * h_mean + 6)) - 0.20 * np.cos(np.radians(4 * h_mean - 63)))
    s_l = 1 + 0.015 * (l_mean - 50) ** 2 / np.sqrt(20 + (l_mean - 50) ** 2)
    s_c, s_h = 1 + 0.045 * c_mean, 1 + 0.015 * c_mean * t
    r_t = (-2 * np.sqrt(c_mean**7 / (c_mean**7 + 25**7))
           * np.sin(np.radians(60 * np.exp(-(((h_mean - 275) / 25) ** 2)))))
    terms = ((l2 - l1) / s_l, (c2 - c1) / s_c, d_hue / s_h)
    return float(np.sqrt(terms[0] ** 2 + terms[1] ** 2 + terms[2] ** 2 + r_t * terms[1] * terms[2]))


def luminance(rgb) -> np.ndarray:
    """WCAG 2 relative luminance of sRGB colours (0-255; the last axis is R, G, B)."""
    return linear(rgb) @ np.array([0.2126, 0.7152, 0.0722])


def contrast(rgb1, rgb2) -> np.ndarray:
    """WCAG 2 contrast ratio (1 to 21) between colours, pixel by pixel for images."""
    l1, l2 = luminance(rgb1), luminance(rgb2)
    return (np.maximum(l1, l2) + 0.05) / (np.minimum(l1, l2) + 0.05)
