"""Gait analysis of lower-back acceleration: axes from gravity, step events, the per-step pipeline.

Modules
-------
masked_filter
    Gaussian smoothing of signals with missing samples (normalised convolution; nothing is invented).
axes
    Vertical and antero-posterior acceleration from the gravity direction (minimal tilt correction).
events
    Foot-flat, heel-strike and toe-off detection from vertical acceleration (:class:`GaitEventDetector`).
integration
    Per-step double integration on the measured samples with resets (Alvarez M1/M2, eqs 1-3).
pipeline
    Calibrated acceleration -> per-step table with every estimator (:class:`StepPipeline`).
estimators
    The step-length estimators M1-M5 (one class each).
k_calibration
    K of M1/M2/M4 and the M5 line fitted to walks over known distances (:class:`KFit`).
k_prior
    A population K that one short walk's K is shrunk toward (:class:`KPrior`, empirical Bayes).
anthropometry
    Leg and foot length from body height when they were not measured.
"""
