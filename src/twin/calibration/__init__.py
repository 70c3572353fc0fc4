"""The makers of the files that say what a tester is: each reads what a lab has (a drawing,
measured temperatures, calibration records) and writes a parameter or coefficients file.

- :mod:`~twin.calibration.geometry` (``twin geometry``): the FMUs' lengths, capacities and
  conductances from the drawing (``scenarios/base/geometry-*.toml``);
- :mod:`~twin.calibration.thermal` (``twin calibrate``): the thermal network fitted to the
  paper's measured temperature rises (``scenarios/calibration/li2017-thermal-network.toml``);
- :mod:`~twin.calibration.identify` (``twin identify``): the error model's coefficients from
  calibration experiments, as a lab finds them (``scenarios/calibration/identified.toml``).
"""
