"""The gait logger of Alvarez et al. (2006), modelled as a PIC16F877-style fixed-point device.

``world`` (motion with ground truth) -> ``sensor`` (two ADXL202) -> ``adc`` (10-bit, timer-sampled) ->
``ring_buffer`` over ``eeprom`` (24LC1025-style) -> ``firmware`` (UART command handler) -> ``transport``.
This package may import ``protocol`` and never ``host``.
"""
