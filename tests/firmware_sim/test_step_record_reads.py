"""The model's I2C reads of the step record, counted against the bus in gpsim: every record's reads and bytes.

Independent truth: gpsim's write log of the MSSP (each read's repeated start, each byte received,
:meth:`~gaitlog.firmware_sim.pic.gpsim_logger.PicLogger.run_bus`). The model prices a read as its data bytes and
``I2C_READ_OVERHEAD`` bytes (control and address sent, the second control byte, the closing byte received); on
the bus that is each received byte plus 4 bytes sent a read.
"""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q
from gaitlog.firmware_sim.algorithms.probe import algorithm_operation_counts
from gaitlog.firmware_sim.fixedpoint import OP_I2C
from gaitlog.firmware_sim.pic import gpsim_logger as gl

needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")


@needs_gpsim
def test_each_records_reads_and_bytes_are_the_buses(simulated_walk):
    """The walk's first 1,200 samples: on every sample with a step record, the model's I2C bytes of step 5 are
    gpsim's received bytes plus 4 a read (no tail write there: the run's first 1,200 samples need none)."""
    codes = simulated_walk[0][:1200]
    h = gl.PicLogger()
    cal = nominal_calibration_q()
    ops = algorithm_operation_counts(codes, cal, 50.0, [0], gravity_shift=h.gravity_shift,
                                     min_gravity_raw=h.min_gravity_raw)
    bus = h.run_bus(codes, cal)
    assert not (bus.page_writes[:, 2] < 32).any() or bus.page_writes[bus.page_writes[:, 2] < 32, 0].min() >= 1200
    reads = {int(k): (int(r), int(b)) for k, r, b in bus.reads}
    assert ops.record_samples.size >= 15 and set(reads) >= set(ops.record_samples.tolist())
    assert kernel.I2C_READ_OVERHEAD == 5
    for k in ops.record_samples.tolist():
        n_reads, received = reads[k]
        assert ops.step5[k, OP_I2C] == received + (kernel.I2C_READ_OVERHEAD - 1) * n_reads, k
    assert np.all([reads[k][0] > 5 for k in ops.record_samples.tolist()])
