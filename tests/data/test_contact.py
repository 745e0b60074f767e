"""The simulation's contact mechanics: the friction cone, stick through each reversal of a slip
until breakaway, Cattaneo-Mindlin partial slip, and shear without slip in pressing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import butter, sosfiltfilt

from slipbench.data.contact import annulus_travel, breakaway, slip_annulus
from slipbench.data.synth import (
    MATERIAL_MODELS,
    SENSORS,
    Design,
    Physics,
    calibrated_forces,
    generate,
    make_unit,
    with_physics,
)

MU = 0.75


@settings(max_examples=50, deadline=None)
@given(q=st.floats(0.0, 1.0), normal=st.floats(0.01, 20.0))
def test_the_slip_annulus_is_cattaneo_mindlins(q, normal):
    """The stick core's radius is a (1 - Q / mu P)^(1/3): the slipping area grows from none
    without shear to the whole contact at the cone's edge, whatever the load."""
    area = slip_annulus(np.array([q * MU * normal]), np.array([normal]), MU)[0]
    assert area == pytest.approx(1 - ((1 - q) ** (1 / 3)) ** 2, abs=1e-9)
    assert 0.0 <= area <= 1.0


def test_shear_at_a_constant_load_sweeps_the_annulus_and_proportional_loading_does_not():
    n = 1000
    ramp = np.linspace(0.0, 1.0, n)
    # the shear rises to 99 % of the cone under a constant 2 N: the edge slips ever faster
    swept = annulus_travel(0.99 * MU * 2.0 * ramp, np.full(n, 2.0), MU)
    assert swept[-1] == pytest.approx(slip_annulus(np.array([0.99 * MU]), np.ones(1), MU)[0])
    steps = np.diff(swept)
    assert (steps >= 0).all() and steps[-100:].mean() > 2.5 * steps[:100].mean()
    # shear and load rising together at 0.9 mu: inside the cone at every increment, no slip
    # (Mindlin-Deresiewicz), though the same ratio held at a constant load would slip
    load = 0.1 + 2.0 * ramp
    assert annulus_travel(0.9 * MU * load, load, MU)[-1] == 0.0
    # unloading back to no shear sweeps it back: micro-slip in reverse
    there_and_back = np.r_[0.99 * MU * 2.0 * ramp, 0.99 * MU * 2.0 * ramp[::-1]]
    assert annulus_travel(there_and_back, np.full(2 * n, 2.0), MU)[-1] == pytest.approx(
        2 * swept[-1]
    )


def test_each_leg_breaks_away_from_where_the_pull_first_reaches_the_limit():
    leg = np.repeat([0, 1, 2], 5)
    loading = np.array([0, 1, 2, 3, 1, 0, 0, 0, 0, 0, 3, 0, 0, 0, 0], float)
    limit = np.full(15, 2.0)
    expected = np.r_[[0, 0, 1, 1, 1], [0] * 5, [1] * 5].astype(bool)
    assert np.array_equal(breakaway(loading, limit, leg), expected)


@pytest.fixture(scope="module")
def drag():
    """One OptoForce20 unit dragged over aluminum at 75 mm/s in 10 s recordings (four
    reversals each), with no trial or recording signatures: the friction is the material's."""
    design = with_physics(
        Design(
            sensors=("OptoForce20",),
            materials=("aluminum",),
            slip_speeds=(75.0,),
            press_s_per_material=0.0,
            free_speeds=(),
            onset_s_per_cell=0.0,
            long_press_s_per_material=0.0,
            slip_trials=2,
        ),
        signature_spread=0.0,
    )
    rec, samples, labels = generate(scale=0.1, seed=3, design=design)
    return rec[rec["sensor_instance"] == "index"], samples, labels


def test_slip_sticks_through_each_reversal_and_breaks_away_at_static_friction(drag):
    rec, samples, labels = drag
    p, mu_k = Physics(), MATERIAL_MODELS["aluminum"].friction
    unit = make_unit(3, "OptoForce20", "index", p)
    breaks = 0
    for r in rec["recording_id"]:
        f = calibrated_forces(samples[r], SENSORS["OptoForce20"], unit)
        ratio = np.abs(f[0]) / f[2]
        lab = labels[r]
        assert np.median(ratio[lab == 1]) == pytest.approx(mu_k, rel=0.08)
        for onset in np.flatnonzero(np.diff(lab) == 1) + 1:
            if onset < 200:
                continue
            breaks += 1
            # the bent finger's shear peaks at static friction, then drops to kinetic
            before = ratio[onset - 10 : onset].max()
            assert before == pytest.approx(p.static_friction_ratio * mu_k, rel=0.08), r
            # and a reversal before it passed the shear through zero, the contact stuck
            assert ratio[onset - 200 : onset].min() < 0.3 * mu_k, r
    assert breaks >= 4


def test_pressing_loads_the_contact_up_to_the_cone_without_crossing_it():
    """Every pressing task keeps the (slowly varying) shear inside the friction cone, and
    lifting and pushing carry it close to the edge (a safety margin of 1.1-1.7). No trial or
    recording signatures: the cone is the material's, the contact's frame the sensor's."""
    design = with_physics(
        Design(
            sensors=("OptoForce20",),
            slip_s_per_cell=0.0,
            free_speeds=(),
            onset_s_per_cell=0.0,
            long_press_s_per_material=0.0,
        ),
        signature_spread=0.0,
    )
    rec, samples, _ = generate(scale=0.03, seed=2, design=design)
    sos = butter(2, 20.0, fs=1000.0, output="sos")  # the loads, without ringing and crackle
    near_edge = 0
    for r in rec.itertuples():
        unit = make_unit(2, "OptoForce20", r.sensor_instance, Physics())
        f = sosfiltfilt(
            sos, calibrated_forces(samples[r.recording_id], SENSORS["OptoForce20"], unit)
        )
        loaded = f[2] > 0.2
        ratio = np.hypot(f[0], f[1])[loaded] / f[2][loaded]
        mu_s = Physics().static_friction_ratio * MATERIAL_MODELS[r.material].friction
        assert loaded.sum() < 50 or np.percentile(ratio, 99) < mu_s, r.recording_id
        near_edge += loaded.sum() >= 50 and np.percentile(ratio, 90) > 0.6 * mu_s
    assert near_edge > 0.3 * len(rec), near_edge
