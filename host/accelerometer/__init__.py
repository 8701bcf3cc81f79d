"""Accelerometer calibration: static windows of a calibration session and the fit of offsets, scales, axes."""
