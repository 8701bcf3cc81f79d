"""The PIC16F877's arithmetic kernels in PIC16 assembly (``*.asm``, ``CONVENTION.md``), run in gpsim and
checked bit for bit against :mod:`gaitlog.firmware_sim.fixedpoint` (:mod:`gaitlog.firmware_sim.pic.gpsim_bench`)."""
