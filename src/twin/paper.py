"""The seed paper's numbers the twin is calibrated to or validated against (docs/reference/facts.md section 2).

Li W., Hu Z., Yang Y., Fan B., Zhou H.: Modeling and verification of comprehensive errors of
real-time wear-depth detecting for spherical plain bearing tester. J. Cent. South Univ. 2017,
24: 533-545, DOI 10.1007/s11771-017-3456-2.
"""

from __future__ import annotations

#: duration of the thermal experiment, s [paper]
EXPERIMENT_S = 480 * 60

#: temperature rises over the 480 min, K, at the eight measuring points [paper].
#: Calibration data for the thermal network.
TEMPERATURE_RISE_K: dict[str, float] = {
    "bearing_block": 6.5,
    "heel_block": 5.8,
    "bearing": 3.2,
    "t_plate": 6.3,
    "base": 6.0,
    "long_pole": 9.6,
    "detecting_frame": 8.9,
    "room": 8.9,
}

#: probe reading at start and end, m [paper]. VALIDATION ONLY: nothing may be fitted to it.
PROBE_START_M = 4.805e-3
PROBE_END_M = 4.784e-3
DRIFT_M = PROBE_END_M - PROBE_START_M  # -0.021 mm: the reading falls

#: the paper's FEM part results at the measured rises, m (Z down; docs/reference/facts.md section 2).
#: 'bearing_block' is derived from the paper's arithmetic (Table 6 is not in the text).
FEM_PARTS_M: dict[str, float] = {
    "bearing_block": -0.018e-3,  # inner ring of the roller bearing rises [derived]
    "t_plate": 0.003e-3,  # T-plate bottom moves down relative to the bearing [paper]
    "detecting_frame": 0.041e-3,  # sensor fixing point moves down [paper]
    "long_pole": 0.040e-3,  # clamp contact point moves down (pole + clamp) [paper]
}
FEM_TOTAL_M = -0.016e-3  # the paper's FEM total (reading falls)
