"""Measuring anytime modules: the profile builder and its trials, the progress bar, calibration,
the catalogue every module should pass (`anytime check`), the program problem sets and the
measurement of a module on what its program feeds it (`anytime profile --upstream`).

This layer sits above `anytime.modules` and `anytime.runtime`; `anytime.profiles` below it is
pure data. The submodules are imported by name (`anytime.measure.builder`); this package
imports none of them, so importing it costs nothing.
"""
