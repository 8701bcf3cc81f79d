"""Speed of the PIC arithmetic (``gaitlog.firmware_sim.fixedpoint``) and of the fixed-point step chain.

Run: ``python benchmarks/bench_fixedpoint.py``. Each primitive runs on 65,536 samples and is timed (best of
7) beside apytypes (the bit-exact oracle of the tests) and a plain Python-int loop, measured in the same
run; results are checked equal before timing. The fixed-point chain (10-bit codes -> one M1-M5 record per
step) is the firmware's on-line step algorithm in the PIC's arithmetic
(``gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm``, ``arithmetic="fixed"``), run on 65,536 samples of a
synthetic tilted walk (target <= 0.2 s, issues 5 and 10; best of 7 after a warm-up that loads the compiled
kernels), beside the same algorithm in float and the offline float chain (``gaitlog.host.gait.pipeline``) on the
same samples. ``benchmarks/bench_online.py`` times it on a simulated walker's recording, with start-up and
memory. Exits 1 if a target is missed.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from _timing import best_of

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gaitlog.firmware_sim.fixedpoint import QFormat, cumsum, div, isqrt, mul_q  # noqa: E402
from gaitlog.units import STANDARD_GRAVITY_M_S2

N = 65_536
PRIMITIVE_TARGET_S = 0.005
CHAIN_TARGET_S = 0.2


def main() -> int:
    import apytypes as apy

    A, QM, OM = apy.APyFixedArray, apy.QuantizationMode, apy.OverflowMode
    rng = np.random.default_rng(1)
    q15 = QFormat(0, 15)
    a = rng.integers(-32768, 32768, N)
    b = rng.integers(-32768, 32768, N)
    aa, B_ = A(a, int_bits=1, frac_bits=15), A(b, int_bits=1, frac_bits=15)
    al, bl = a.tolist(), b.tolist()
    failed = False
    rows: list[tuple[str, float, float, float]] = []

    # Q0.15 multiply, half up, saturate
    def ours_mul() -> np.ndarray:
        return mul_q(a, b, 15, q15)

    def apy_mul() -> object:
        return (aa * B_).cast(int_bits=1, frac_bits=15, quantization=QM.RND, overflow=OM.SAT)

    def py_mul() -> list[int]:
        return [min(32767, max(-32768, (x * y + 0x4000) >> 15)) for x, y in zip(al, bl)]

    assert ours_mul().tolist() == py_mul()
    rows.append(("Q0.15 mul (half up, sat)", best_of(ours_mul), best_of(apy_mul), best_of(py_mul, 3)))

    # Q15.16 running sum in a 32-bit accumulator, saturating (no overflow here) and wrapping
    q1616 = QFormat(15, 16, word_bits=32)
    steps = rng.integers(-(1 << 20), 1 << 20, N)
    sl = steps.tolist()
    ss = A(steps, int_bits=16, frac_bits=16)

    def ours_cs() -> np.ndarray:
        return cumsum(steps, q1616, overflow="wrap")

    def apy_cs() -> object:
        return ss.cumsum().cast(int_bits=16, frac_bits=16, overflow=OM.WRAP)

    def py_cs() -> list[int]:
        acc, out = 0, []
        for v in sl:
            acc = max(-(1 << 31), min((1 << 31) - 1, acc + v))
            out.append(acc)
        return out

    assert ours_cs().tolist() == py_cs()
    rows.append(("Q15.16 cumsum (wrap)", best_of(ours_cs), best_of(apy_cs), best_of(py_cs, 3)))

    def ours_css() -> np.ndarray:
        return cumsum(steps, q1616, overflow="saturate")

    rows.append(("Q15.16 cumsum (saturate)", best_of(ours_css), best_of(apy_cs), best_of(py_cs, 3)))

    # 32/16 divide, truncation towards zero
    n = rng.integers(-(1 << 31), 1 << 31, N)
    d = rng.integers(1, 1 << 15, N) * rng.choice([-1, 1], N)
    nl, dl = n.tolist(), d.tolist()
    na, da = A(n, int_bits=32, frac_bits=0), A(d, int_bits=16, frac_bits=0)

    def ours_div() -> np.ndarray:
        return div(n, d)[0]

    def apy_div() -> object:
        return (na / da).cast(int_bits=32, frac_bits=0, quantization=QM.TRN_ZERO, overflow=OM.SAT)

    def py_div() -> list[int]:
        return [abs(x) // abs(y) * (1 if (x < 0) == (y < 0) else -1) for x, y in zip(nl, dl)]

    assert ours_div().tolist() == py_div()
    rows.append(("32/16 div (to zero)", best_of(ours_div), best_of(apy_div), best_of(py_div, 3)))

    # integer square root (no apytypes equivalent: math.isqrt loop is the reference)
    x = rng.integers(0, 1 << 32, N)
    xl = x.tolist()

    def ours_sqrt() -> np.ndarray:
        return isqrt(x)

    def py_sqrt() -> list[int]:
        return [math.isqrt(v) for v in xl]

    assert ours_sqrt().tolist() == py_sqrt()
    rows.append(("isqrt 32-bit", best_of(ours_sqrt), float("nan"), best_of(py_sqrt, 3)))

    print(f"fixed-point primitives on {N} samples (best of 7; target <= {PRIMITIVE_TARGET_S * 1e3:.1f} ms each)")
    print(f"{'kernel':28s} {'ours ms':>9s} {'apytypes ms':>12s} {'x apy':>7s} {'py loop ms':>11s} {'x loop':>7s}")
    for name, ours, ref, loop in rows:
        ok = ours <= PRIMITIVE_TARGET_S
        failed |= not ok
        ra = f"{ref / ours:7.1f}" if np.isfinite(ref) else "      -"
        rs = f"{ref * 1e3:12.3f}" if np.isfinite(ref) else "           -"
        print(f"{name:28s} {ours * 1e3:9.3f} {rs} {ra} {loop * 1e3:11.2f} {loop / ours:7.0f}"
              f"{'' if ok else '  MISSED'}")

    failed |= not chain_benchmark()
    return 1 if failed else 0


def chain_benchmark() -> bool:
    """The on-line algorithm in fixed point on 65,536 samples of simulated 10-bit walking; True if the target is met."""
    from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
    from gaitlog.firmware_sim.fixedpoint import cycles_per_sample_available
    from gaitlog.protocol.steps import StepConfig

    codes = _walking_codes(N)
    cfg = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.26)
    algs = {a: OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg, arithmetic=a) for a in ("fixed", "float")}
    t = {a: best_of(lambda a=a: alg.run(codes), warmup=True) for a, alg in algs.items()}
    once = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=cfg, arithmetic="fixed")
    n_steps = once.run(codes).n_steps
    cyc, period = once.cycles, cycles_per_sample_available(50.0)
    ok = t["fixed"] <= CHAIN_TARGET_S
    print(f"fixed-point chain = on-line step algorithm, fixed point (codes -> M1-M5 records) on {N} samples: "
          f"{t['fixed']:.3f} s (target <= {CHAIN_TARGET_S} s), {n_steps} steps; PIC cycles per sample {cyc.mean:.0f} "
          f"mean, {cyc.worst} worst, worst backlog {cyc.worst_backlog / period:.2f} sample periods of {period:.0f}"
          f"{'' if ok else '  MISSED'}")
    print(f"  same algorithm in float: {t['float']:.3f} s (fixed/float {t['fixed'] / t['float']:.2f})")
    import warnings

    from gaitlog.host.gait.pipeline import StepPipeline

    acc = (codes.astype(np.float64) - 512.0) / 256.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t_f = best_of(lambda: StepPipeline(leg_length_m=0.9, foot_length_m=0.26).run(acc, sampling_rate_hz=50.0),
                      warmup=True)
    print(f"  baseline offline float chain (gaitlog.host.gait.pipeline) on the same samples: {t_f:.3f} s (ratio fixed/offline "
          f"{t['fixed'] / t_f:.2f})")
    return ok


def _walking_codes(n: int) -> np.ndarray:
    """10-bit codes of a tilted sensor on a CoM moving vertically at 1.8 steps/s with 2.5 cm excursion."""
    rng = np.random.default_rng(7)
    sampling_rate_hz = 50.0
    t = np.arange(n) / sampling_rate_hz
    f = 1.8 * (1 + 0.05 * np.sin(2 * np.pi * t / 60.0))
    phase = 2 * np.pi * np.cumsum(f) / sampling_rate_hz
    a_v_g = 0.0125 * (2 * np.pi * f) ** 2 * np.cos(phase) / STANDARD_GRAVITY_M_S2
    a_ap_g = 0.15 * np.sin(phase + 0.5)
    up = np.array([0.2, 0.1, 0.9747])
    fwd = np.cross([0.0, 1.0, 0.0], up)
    fwd /= np.linalg.norm(fwd)
    acc = (1 + a_v_g)[:, None] * up + a_ap_g[:, None] * fwd + rng.normal(0, 0.004, (n, 3))
    return np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)


if __name__ == "__main__":
    sys.exit(main())
