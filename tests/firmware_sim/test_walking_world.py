"""Walking world: truth self-consistency, protocol geometry, gait ranges from the literature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid
from scipy.spatial.transform import Rotation

from gaitlog.firmware_sim.world.base import Motion, MotionSource
from gaitlog.firmware_sim.world.corridor import CorridorPath
from gaitlog.firmware_sim.world.subject import Subject, random_subjects
from gaitlog.firmware_sim.world.walk_plan import WalkPlan
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.units import STANDARD_GRAVITY_M_S2

ONE_EXCURSION = WalkPlan(speeds=("preferred",), initial_stand_s=3.0, final_stand_s=2.0)
TWO_EXCURSIONS = WalkPlan(speeds=("fast", "slow"), initial_stand_s=3.0, final_stand_s=2.0, rest_s=12.0,
                                 rest_postures=("sitting",))


@pytest.fixture(scope="module")
def fine() -> Motion:
    """One preferred-speed excursion of a random subject at 1 kHz with the world trajectory."""
    subject = random_subjects(3, seed=11)[2]
    return Walking(subject=subject, walk_plan=ONE_EXCURSION, seed=5, include_trajectory=True).render(1000.0)


@pytest.fixture(scope="module")
def sitting() -> Motion:
    return Walking(walk_plan=TWO_EXCURSIONS, seed=2, include_trajectory=True).render(200.0)


def test_is_a_motion_source() -> None:
    assert isinstance(Walking(), MotionSource)


def test_double_integration_of_rendered_acceleration_reproduces_truth(fine: Motion) -> None:
    """Rendered specific force -> world frame -> minus gravity -> integrate twice == truth positions."""
    tr = fine.truth["trajectory"]
    steps = fine.truth["steps"]
    t = fine.t_s
    acc_w = np.einsum("nij,nj->ni", tr["world_from_device"], fine.acc_g) * STANDARD_GRAVITY_M_S2
    acc_w[:, 2] -= STANDARD_GRAVITY_M_S2
    rng = np.random.default_rng(0)
    for i in rng.choice(np.flatnonzero(steps["phase"] == "steady"), size=12, replace=False):
        i0 = int(np.ceil(steps["foot_flat_s"][i] * fine.sampling_rate_hz))
        i1 = int(np.floor(steps["next_foot_flat_s"][i] * fine.sampling_rate_hz)) + 1
        a = acc_w[i0:i1]
        v = tr["sensor_velocity_m_s"][i0] + cumulative_trapezoid(a, t[i0:i1], axis=0, initial=0.0)
        p = tr["sensor_position_m"][i0] + cumulative_trapezoid(v, t[i0:i1], axis=0, initial=0.0)
        np.testing.assert_allclose(p, tr["sensor_position_m"][i0:i1], atol=2e-5)
        np.testing.assert_allclose(v, tr["sensor_velocity_m_s"][i0:i1], atol=2e-4)
        # The truth excursion (max - min of the sensor's height between foot-flats) is what integration sees.
        # (the samples start/end up to one period inside the foot-flat instants: allow that much travel)
        edge = np.abs(tr["sensor_velocity_m_s"][[i0, i1 - 1], 2]).max() / fine.sampling_rate_hz
        assert np.ptp(p[:, 2]) == pytest.approx(steps["sensor_excursion_m"][i], abs=2e-5 + edge)


def test_rotation_is_orthonormal_and_gravity_consistent(fine: Motion) -> None:
    rot = fine.truth["trajectory"]["world_from_device"][::997]
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", rot, rot), np.broadcast_to(np.eye(3), rot.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-12)


def test_at_rest_the_norm_is_one_g_and_x_points_up(fine: Motion, sitting: Motion) -> None:
    for m in (fine, sitting):
        exc = m.truth["excursions"]
        rest = (m.t_s < exc["t_start_s"][0] - 0.01) | (m.t_s > exc["t_stop_s"][-1] + 0.01)
        for a, b in zip(exc["t_stop_s"][:-1], exc["t_start_s"][1:]):
            rest |= (m.t_s > a + 0.01) & (m.t_s < b - 0.01)
        norm = np.linalg.norm(m.acc_g[rest], axis=1)
        # Sit-down / stand-up transitions move the body: exactly 1 g only where it is still.
        # (a sample is still when it has not moved from either neighbour: a sample just after a transition
        # starts has moved by ~jerk·dt³, which can be below any position threshold)
        moved = np.linalg.norm(np.diff(m.truth["trajectory"]["sensor_position_m"][rest], axis=0), axis=1)
        still = (moved[:-1] < 1e-12) & (moved[1:] < 1e-12)
        assert still.sum() > 0.5 * rest.sum()
        np.testing.assert_allclose(norm[1:-1][still], 1.0, atol=1e-12)
    # Device x is nominally vertical: standing, tilted by mounting and trunk lean only (< 25 deg).
    assert fine.acc_g[0, 0] > np.cos(np.deg2rad(25.0))


def test_sitting_rest_tilts_the_trunk(sitting: Motion) -> None:
    rest = sitting.truth["rests"]
    assert list(rest["posture"]) == ["sitting"]
    mid = int(0.5 * (rest["t_start_s"][0] + rest["t_stop_s"][0]) * sitting.sampling_rate_hz)
    stand = sitting.acc_g[0]
    seated = sitting.acc_g[mid]
    angle = np.degrees(np.arccos(np.clip(stand @ seated, -1, 1)))
    assert 8.0 < angle < 16.0  # trunk reclined by 12 degrees


def test_step_lengths_add_up_to_the_path(fine: Motion, sitting: Motion) -> None:
    for m in (fine, sitting):
        st, ex = m.truth["steps"], m.truth["excursions"]
        for k in range(ex["speed_label"].size):
            sel = st["excursion"] == k
            total = st["length_m"][sel].sum() + ex["initiation_travel_m"][k] + ex["termination_travel_m"][k]
            assert total == pytest.approx(ex["path_length_m"][k], abs=1e-9)
            # The path is the 200 m of corridor plus what the turn adds (< 1 m).
            assert 0.0 < ex["path_length_m"][k] - ex["corridor_distance_m"][k] < 1.0
            assert ex["corridor_distance_m"][k] == 200.0


def test_lap_marks_match_the_distance_walked(fine: Motion) -> None:
    laps, tr = fine.truth["laps"], fine.truth["trajectory"]
    np.testing.assert_array_equal(fine.marker_times_s, laps["time_s"])
    assert np.all(np.diff(laps["time_s"]) > 0)
    np.testing.assert_array_equal(laps["distance_m"], ONE_EXCURSION.lap_marks_m)
    com_x = tr["com_position_m"][:, 0]
    # Corridor distance of the centre of mass at each mark: x on the way out, 200 - x on the way back.
    for d, t_mark in zip(laps["distance_m"], laps["time_s"]):
        x = np.interp(t_mark, fine.t_s, com_x)
        measured = x if d <= 100.0 else 200.0 - x
        # CoM lateral sway moves x by < 1 mm in the straights; interpolation at 1 kHz ~ 1 mm.
        assert measured == pytest.approx(d, abs=0.005), d
    # Consecutive 20 m sections: cumulative distance is consistent.
    np.testing.assert_allclose(np.diff(laps["cumulative_distance_m"]), np.diff(laps["distance_m"]))


def test_gait_events_are_ordered_and_alternate(fine: Motion) -> None:
    st = fine.truth["steps"]
    assert np.all(st["heel_strike_s"] < st["foot_flat_s"])
    assert np.all(st["foot_flat_s"] < st["toe_off_s"])
    assert np.all(st["toe_off_s"] < st["next_heel_strike_s"])
    assert np.all(st["heel_strike_s"] <= st["com_min_s"]) and np.all(st["com_min_s"] < st["next_heel_strike_s"])
    np.testing.assert_array_equal(st["next_heel_strike_s"][:-1], st["heel_strike_s"][1:])
    assert np.all(st["side"][1:] != st["side"][:-1])
    # Double support 8-45 % of the step; the CoM is lowest around its end, not at foot-flat.
    ds = (st["toe_off_s"] - st["heel_strike_s"]) / (st["next_heel_strike_s"] - st["heel_strike_s"])
    ds = ds[st["phase"] != "termination"]
    assert 0.08 <= ds.min() and ds.max() <= 0.45
    assert np.median(np.abs(st["com_min_s"] - st["foot_flat_s"])) > 0.003


def test_walking_speed_is_forward_and_continuous(fine: Motion) -> None:
    tr = fine.truth["trajectory"]
    st = fine.truth["steps"]
    walk = (fine.t_s > st["heel_strike_s"][0]) & (fine.t_s < st["heel_strike_s"][-1])
    v = tr["sensor_velocity_m_s"][walk]
    speed = np.linalg.norm(v[:, :2], axis=1)
    assert speed.min() > 0.1 and speed.max() < 2.5
    # The centre of mass never moves backward along the path while walking.
    com = tr["com_position_m"]
    assert np.all(np.diff(fine.truth["laps"]["time_s"]) > 0)
    x_out = com[walk, 0][: np.argmax(com[walk, 0])]
    assert np.all(np.diff(x_out) > -1e-4)
    # No jumps: acceleration bounded (heel strikes may brush the ADXL202's +-2 g, nothing beyond 2.5 g).
    assert np.abs(fine.acc_g).max() < 2.5


def test_contact_timing_matches_real_lower_back_recordings() -> None:
    """Double support and the centre of mass's low point, as measured on real people.

    Reference: the IPOL lower-back recordings (Voisard et al. 2023; 9 subjects, 52 trials, 1298 straight
    steps with foot-sensor events, 100 Hz): double support 0.14 s median (IQR 0.11-0.16), 24 % of the step
    (IQR 21-27 %; per subject 18-29 %), i.e. ~12 % of the gait cycle per side as in the literature (Perry:
    10-12 % at preferred speed, longer when slower); the centre of mass is lowest (peak of the 3 Hz
    low-passed vertical acceleration, or minimum of its double integral) 40 ms after heel strike (IQR
    20-60 ms, 0.27 of double support) and 100 ms before the trailing toe-off (IQR 80-110 ms).
    """
    walk_plan = WalkPlan(corridor_length_m=30.0, speeds=("slow", "preferred", "fast"), rest_s=6.0,
                          rest_postures=("standing",), initial_stand_s=1.0, final_stand_s=1.0,
                          lap_marks_m=(0.0, 10.0, 30.0, 50.0, 60.0))
    ds_med: dict[str, list[float]] = {"slow": [], "preferred": [], "fast": []}
    for i, subject in enumerate(random_subjects(6, seed=2)):
        st = Walking(subject=subject, walk_plan=walk_plan, seed=i).render(50.0).truth["steps"]
        for label in ds_med:
            sel = (st["speed_label"] == label) & (st["phase"] == "steady")
            ds = st["toe_off_s"][sel] - st["heel_strike_s"][sel]
            ds_med[label].append(float(np.median(ds / (st["next_heel_strike_s"][sel] - st["heel_strike_s"][sel]))))
            if label != "preferred":
                continue
            low = st["com_min_s"][sel] - st["heel_strike_s"][sel]
            assert 0.10 <= np.median(ds) <= 0.20, np.median(ds)
            assert 0.0 <= np.median(low) <= 0.09, np.median(low)
            assert 0.06 <= np.median(st["toe_off_s"][sel] - st["com_min_s"][sel]) <= 0.14
            # anatomical foot-flat (forefoot down, ~8 % of the gait cycle) after the low point, before toe-off
            assert np.median(st["foot_flat_s"][sel] - st["com_min_s"][sel]) > 0.0
    pref = np.array(ds_med["preferred"])
    assert 0.17 <= pref.min() and pref.max() <= 0.33 and 0.20 <= np.median(pref) <= 0.28
    # longer double support when slower, shorter when faster (every subject)
    assert np.all(np.array(ds_med["slow"]) > pref) and np.all(np.array(ds_med["fast"]) < pref)


@pytest.mark.parametrize("subject", random_subjects(3, seed=1) + [Subject()], ids=lambda s: s.subject_id)
def test_cadence_and_step_length_within_literature_ranges(subject: Subject) -> None:
    """Steady steps: step length and cadence vs speed as in healthy adults.

    Ranges: cadence 75-150 steps/min across slow-fast walking, step length 0.5-0.95 m; both rise with speed
    (Grieve 1968; Bohannon 1997: comfortable 1.3-1.5 m/s in men 20-49 y; Sekiya & Nagasaki 1998 walk ratio).
    """
    walk_plan = WalkPlan(corridor_length_m=30.0, speeds=("slow", "preferred", "fast"), rest_s=6.0,
                          rest_postures=("standing",), initial_stand_s=1.0, final_stand_s=1.0,
                          lap_marks_m=(0.0, 10.0, 30.0, 50.0, 60.0))
    m = Walking(subject=subject, walk_plan=walk_plan, seed=3).render(50.0)
    st = m.truth["steps"]
    cad, length = [], []
    for label in ("slow", "preferred", "fast"):
        sel = (st["speed_label"] == label) & (st["phase"] == "steady")
        assert sel.sum() > 10
        dur = st["next_heel_strike_s"][sel] - st["heel_strike_s"][sel]
        cad.append(60.0 / np.median(dur))
        length.append(np.median(st["length_m"][sel]))
        assert 75.0 <= cad[-1] <= 150.0, (label, cad[-1])
        assert 0.5 <= length[-1] <= 0.95, (label, length[-1])
        speed = np.median(st["speed_m_s"][sel])
        assert speed == pytest.approx(subject.speed_m_s(label), rel=0.06)
    assert cad[0] < cad[1] < cad[2] and length[0] < length[1] < length[2]
    # Step-to-step variability within a few percent (CV of steady step length 1-6 %).
    sel = (st["speed_label"] == "preferred") & (st["phase"] == "steady")
    cv = np.std(st["length_m"][sel]) / np.mean(st["length_m"][sel])
    assert 0.01 < cv < 0.06


def test_pendulum_constant_differs_between_subjects_and_speeds() -> None:
    """K = S / (2 sqrt(2 l h)) of the sensor's excursion is per subject and changes with speed."""
    walk_plan = WalkPlan(corridor_length_m=20.0, speeds=("preferred", "fast"), rest_s=6.0,
                          rest_postures=("standing",), initial_stand_s=1.0, final_stand_s=1.0,
                          lap_marks_m=(0.0, 40.0))
    ks = []
    for s in random_subjects(6, seed=4):
        st = Walking(subject=s, walk_plan=walk_plan, seed=1).render(20.0).truth["steps"]
        per_speed = []
        for label in ("preferred", "fast"):
            sel = (st["speed_label"] == label) & (st["phase"] == "steady")
            h = st["sensor_excursion_m"][sel]
            per_speed.append(np.sum(st["length_m"][sel]) / np.sum(2 * np.sqrt(2 * s.leg_length_m * h - h**2)))
        ks.append(per_speed)
    ks = np.array(ks)
    assert np.all((ks > 0.9) & (ks < 2.5))
    assert np.std(ks[:, 0]) / np.mean(ks[:, 0]) > 0.04  # one K does not fit everyone
    assert np.max(np.abs(ks[:, 1] / ks[:, 0] - 1.0)) > 0.02  # nor every speed


def test_seeded_and_reproducible() -> None:
    walk_plan = WalkPlan(corridor_length_m=10.0, speeds=("preferred",), initial_stand_s=1.0,
                          final_stand_s=1.0, lap_marks_m=(0.0, 20.0))
    a = Walking(walk_plan=walk_plan, seed=9).render(100.0)
    b = Walking(walk_plan=walk_plan, seed=9).render(100.0)
    c = Walking(walk_plan=walk_plan, seed=10).render(100.0)
    np.testing.assert_array_equal(a.acc_g, b.acc_g)
    assert a.acc_g.shape != c.acc_g.shape or not np.array_equal(a.acc_g, c.acc_g)
    assert random_subjects(4, seed=3) == random_subjects(4, seed=3)


def test_mounting_rotation_is_applied() -> None:
    walk_plan = WalkPlan(corridor_length_m=10.0, speeds=("preferred",), initial_stand_s=1.0,
                          final_stand_s=1.0, lap_marks_m=(0.0, 20.0))
    level = Subject(mounting_rotation_deg=(0.0, 0.0, 0.0), stand_lean_deg=0.0)
    tilted = Subject(mounting_rotation_deg=(0.0, 10.0, 0.0), stand_lean_deg=0.0)
    a0 = Walking(subject=level, walk_plan=walk_plan).render(50.0).acc_g[0]
    a1 = Walking(subject=tilted, walk_plan=walk_plan).render(50.0).acc_g[0]
    np.testing.assert_allclose(a0, [1.0, 0.0, 0.0], atol=1e-12)
    expected = Rotation.from_rotvec([0.0, np.deg2rad(10.0), 0.0]).as_matrix().T @ a0
    np.testing.assert_allclose(a1, expected, atol=1e-12)


def test_corridor_path_geometry() -> None:
    p = CorridorPath(corridor_length_m=100.0, turn_radius_m=0.5)
    s = np.linspace(0.0, p.length_m, 20001)
    xy = p.position_m(s)
    # Arc length of the sampled path equals the parameter.
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert seg.sum() == pytest.approx(p.length_m, rel=1e-6)
    assert xy[:, 0].max() == pytest.approx(100.0, abs=1e-6)
    assert xy[-1, 0] == pytest.approx(0.0, abs=1e-6)
    d = np.array([0.0, 30.0, 99.9, 100.0, 100.1, 170.0, 200.0])
    np.testing.assert_allclose(p.corridor_distance_m(p.s_at_corridor_distance(d)), d, atol=1e-6)


def test_bad_parameters_are_rejected() -> None:
    with pytest.raises(ValueError, match="leg_length_m"):
        Subject(leg_length_m=2.0)
    with pytest.raises(ValueError, match="speed label"):
        WalkPlan(speeds=("brisk",))
    with pytest.raises(ValueError, match="rate_hz"):
        Walking().render(0.0)
