"""The HTML calibration report and its figures (matplotlib, imported only here)."""
