"""The embedded default dataset: a physical simulation of the paper's design of experiments.

Three sensor types (Nano17, OptoForce20, BioTac SP) on the fingers of a hand, five materials,
slip at four average speeds, pressing (palpation) on each material, and free-space motion at
three speeds. Every effect is a field of :class:`Physics` and is described in ``datasets.md``.
The model is physical and is *not* fitted to the paper's accuracies.

All randomness flows from one seed. Each recording draws from its own stream, keyed by what it
is (sensor, instance, scenario, material, speed, trial), so the result does not depend on the
order of generation; the instances of one sensor type share each trial's arm motion, as the
paper sampled them concurrently.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

from .data import write_dataset

MATERIALS = ("aluminum", "PVC", "neoprene", "cardboard", "plywood")
SLIP_SPEEDS = (5.0, 25.0, 50.0, 75.0)
FREE_SPACE_SPEEDS = (25.0, 50.0, 75.0)
MODEL_VERSION = 1  # bump when the simulation changes, so cached datasets are regenerated


@dataclass(frozen=True)
class Sensor:
    """One sensor type: sampling, channels and its mechanics."""

    rate_hz: float
    instances: tuple[str, ...]
    channels: tuple[str, ...]
    unit: str
    units_per_newton: float
    noise_floor_n: float  # force sensitivity: white noise std of the force estimate, in N
    skin_cutoff_hz: float | None  # rubber skin as a mechanical low-pass; None: thin coating
    idle_coupling: float  # how much of the arm's idle vibration reaches the sensor
    resonance_hz: float  # finger + sensor structure, rung by stick-slip snaps and impacts
    highpass_hz: float | None = None  # BioTac SP: only the high-pass pressure channel is used


SENSORS: dict[str, Sensor] = {
    "Nano17": Sensor(1000.0, ("index", "middle", "little"), ("g1", "g2", "g3", "g4", "g5", "g6"),
                     "N", 1.0, 0.006, None, 1.0, 65.0),
    "OptoForce20": Sensor(1000.0, ("index", "middle", "little"), ("fx", "fy", "fz"),
                          "count", 400.0, 0.0025, 250.0, 0.0, 62.0),
    "BioTacSP": Sensor(850.0, ("index", "middle"), ("pac",), "count", 100.0, 0.010, 250.0, 0.8, 68.0, 10.0),
}


@dataclass(frozen=True)
class Material:
    """Tribology of one surface."""

    critical_slip_mm: float  # mean sliding distance between two stick-slip snaps
    snap_gain: float  # relative size of the force drop at a snap
    resonance_scale: float  # soft surfaces lower the ringing frequency
    damping: float  # damping ratio of the ringing after a snap
    smear_hz: float | None  # soft surfaces smear snaps: low-pass on the event train
    texture_period_mm: float  # spatial period of the surface (grain, corrugation, brushing)
    texture_gain: float
    fibre_noise_gain: float  # broadband rubbing noise (cardboard fibres)
    hardness: float  # impact transient when a finger lands on it while pressing


MATERIAL_MODELS: dict[str, Material] = {
    "aluminum": Material(0.4, 1.0, 1.00, 0.06, None, 0.08, 0.10, 0.0, 1.0),
    "PVC": Material(0.5, 0.8, 0.95, 0.08, None, 0.25, 0.15, 0.0, 0.8),
    "neoprene": Material(1.5, 0.35, 0.70, 0.30, 30.0, 1.00, 0.10, 0.0, 0.2),
    "cardboard": Material(0.6, 0.6, 1.00, 0.12, None, 0.80, 0.30, 0.5, 0.5),
    "plywood": Material(0.5, 0.8, 1.00, 0.08, None, 1.60, 0.60, 0.1, 0.7),
}


@dataclass(frozen=True)
class Physics:
    """Every effect of the simulation, with its size. Forces are in newtons."""

    path_mm: float = 180.0  # back-and-forth drag path; speed ramps 0 -> 2 x average -> 0 per pass
    stick_speed_mm_s: float = 0.5  # below this the contact sticks: no snaps, slip label off
    normal_force_n: tuple[float, float] = (0.5, 2.0)  # range of per-trial contact force
    arm_oscillation_hz: tuple[float, float] = (1.0, 3.0)  # natural oscillation of the moving arm
    arm_oscillation_depth: float = 0.15  # relative normal-force modulation while dragging
    friction: float = 0.6  # Coulomb coefficient: mean tangential / normal force while sliding
    snap_n_per_n: float = 0.03  # snap force drop per newton of normal force at 25 mm/s
    snap_speed_exponent: float = 0.5  # snap size grows with local speed as (v / 25 mm/s)^k
    texture_n_per_n: float = 0.01  # texture force per newton of normal force
    fibre_noise_n: float = 0.008  # rubbing noise at fibre gain 1 and 25 mm/s
    idle_hz: float = 200.0  # the arm's idling vibration
    idle_n: float = 0.008
    press_force_n: tuple[float, float] = (0.2, 4.0)  # palpation force levels
    press_rate_hz: tuple[float, float] = (0.1, 4.0)  # palpation frequencies
    press_shear_ratio: float = 0.2  # shear that a curling finger puts on the surface
    impact_n: float = 0.02  # impact transient at hardness 1 and a 1 Hz palpation
    crackle_n: float = 0.004  # fibres and grain crushing under load (cardboard, plywood)
    inertial_n: float = 0.004  # fingertip inertia under free-space arm motion at 25 mm/s
    jerk_n: float = 0.02  # transient when a free-space motion segment starts or stops
    gear_hz_per_mm_s: float = 1.2  # drive vibration tone: frequency per mm/s of arm speed
    gear_n: float = 0.003  # its size at 25 mm/s
    unit_gain_sd: float = 0.10  # unit-to-unit spread (log-normal sd) of gain
    unit_noise_sd: float = 0.20  # ... of the noise floor
    unit_resonance_sd: float = 0.05  # ... of the resonance frequency
    unit_skin_sd: float = 0.10  # ... of the skin's cut-off frequency


@dataclass(frozen=True)
class Design:
    """How much of each scenario, in seconds per sensor instance at scale 1.0 (~8 M samples)."""

    slip_s_per_cell: float = 200.0  # per material x speed: 20 cells, half the data
    press_s_per_material: float = 400.0  # a quarter of the data
    free_s_per_speed: float = 2000.0 / 3  # a quarter of the data
    slip_trials: int = 8  # recordings per material x speed
    press_trials: int = 8  # recordings per material
    free_trials: int = 12  # recordings per speed (joint-configuration sequences)
    materials: tuple[str, ...] = MATERIALS
    slip_speeds: tuple[float, ...] = SLIP_SPEEDS
    free_speeds: tuple[float, ...] = FREE_SPACE_SPEEDS
    sensors: tuple[str, ...] = tuple(SENSORS)
    physics: Physics = field(default_factory=Physics)


def _rng(seed: int, *key: object) -> np.random.Generator:
    words = [zlib.crc32(str(k).encode()) for k in key]
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=words))


@dataclass(frozen=True)
class Unit:
    """One physical sensor: how it differs from its nominal type."""

    gain: float
    noise: float
    resonance_hz: float
    skin_cutoff_hz: float | None
    mixing: np.ndarray  # (n_channels, 3): force -> channels


def make_unit(seed: int, sensor_type: str, instance: str, physics: Physics) -> Unit:
    s = SENSORS[sensor_type]
    rng = _rng(seed, "unit", sensor_type, instance)
    gain = float(np.exp(rng.normal(0, physics.unit_gain_sd)))
    noise = float(np.exp(rng.normal(0, physics.unit_noise_sd)))
    resonance = s.resonance_hz * float(np.exp(rng.normal(0, physics.unit_resonance_sd)))
    skin = None if s.skin_cutoff_hz is None else s.skin_cutoff_hz * float(np.exp(rng.normal(0, physics.unit_skin_sd)))
    n = len(s.channels)
    if n == 3:
        mixing = np.eye(3) + rng.normal(0, 0.03, (3, 3))  # cross-talk of an optical 3-axis cell
    elif n == 1:
        mixing = np.array([[0.3, 0.3, 1.0]])  # fluid pressure: mostly normal load
    else:
        # strain gauges: a well-conditioned calibration matrix, normalised so that
        # ||mixing @ f|| ~ ||f|| and the noise floor keeps its meaning in newtons
        q, _ = np.linalg.qr(rng.normal(size=(n, 3)))
        mixing = q * np.exp(rng.normal(0, 0.05, 3))
    return Unit(gain, noise, resonance, skin, mixing)


def _resonate(impulses: np.ndarray, f0: float, damping: float, fs: float) -> np.ndarray:
    """Ring a damped oscillator at f0 with each impulse (a 2-pole IIR resonator)."""
    w = 2 * np.pi * min(f0, 0.45 * fs) / fs
    r = np.exp(-damping * w)
    return signal.lfilter([np.sin(w)], [1.0, -2 * r * np.cos(w), r * r], impulses)


def _lowpass(x: np.ndarray, cutoff: float, fs: float, order: int = 2, axis: int = -1) -> np.ndarray:
    if cutoff >= 0.49 * fs:
        return x
    sos = signal.butter(order, cutoff, fs=fs, output="sos")
    return signal.sosfilt(sos, x, axis=axis)


def _events(distance_mm: np.ndarray, mean_spacing: float, rng: np.random.Generator) -> np.ndarray:
    """Positions (mm of travel) of stick-slip snaps: gamma-spaced with the given mean."""
    total = float(distance_mm[-1])
    n_max = int(total / mean_spacing * 1.5) + 16
    pos = np.cumsum(rng.gamma(4.0, mean_spacing / 4.0, n_max))
    return pos[pos < total]


def _slip_forces(n, fs, speed_avg, material, trial_rng, rng, unit, p: Physics):
    """Contact forces (3, n) of the finger dragged across a surface, and per-sample slip label."""
    m = MATERIAL_MODELS[material]
    t = np.arange(n) / fs
    pass_s = 2 * p.path_mm / (2 * speed_avg)  # one leg of the path, there or back
    phase0 = trial_rng.uniform(0, pass_s)
    tt = t + phase0
    speed = speed_avg * (1 - np.cos(2 * np.pi * tt / pass_s))  # mm/s, mean = speed_avg
    direction = np.where((tt // pass_s) % 2 == 0, 1.0, -1.0)
    normal0 = trial_rng.uniform(*p.normal_force_n)
    osc = trial_rng.uniform(*p.arm_oscillation_hz)
    normal = normal0 * (1 + p.arm_oscillation_depth * np.sin(2 * np.pi * osc * t + rng.uniform(0, 2 * np.pi)))
    sliding = speed > p.stick_speed_mm_s
    travel = np.cumsum(np.where(sliding, speed, 0.0)) / fs

    rel = (np.maximum(speed, 1e-9) / 25.0) ** p.snap_speed_exponent
    drop = p.snap_n_per_n * m.snap_gain * normal * rel  # force drop a snap would give now
    pos = _events(travel, m.critical_slip_mm, rng)
    idx = np.searchsorted(travel, pos)
    impulses = np.zeros(n)
    np.add.at(impulses, idx, drop[idx] * rng.lognormal(0, 0.3, len(idx)))
    if m.smear_hz:
        impulses = _lowpass(impulses, m.smear_hz, fs, order=1)
    ringing = _resonate(impulses, unit.resonance_hz * m.resonance_scale, m.damping, fs)
    # stick phase: shear builds up with travel since the last snap, then drops (sawtooth)
    last = np.searchsorted(pos, travel, side="right") - 1
    since = travel - np.r_[0.0, pos][last + 1]
    saw = drop * (np.clip(since / m.critical_slip_mm, 0, 1.5) - 0.5)

    texture = p.texture_n_per_n * m.texture_gain * normal * np.sin(2 * np.pi * travel / m.texture_period_mm)
    fibre = p.fibre_noise_n * m.fibre_noise_gain * np.sqrt(speed / 25.0) * rng.standard_normal(n)
    vib = ringing + texture + fibre
    shear = direction * (p.friction * normal + saw) * sliding + vib
    forces = np.stack([shear, 0.3 * vib * rng.choice([-1, 1]), normal + 0.5 * ringing])
    return forces, sliding


def _press_forces(n, fs, material, trial_rng, rng, unit, p: Physics):
    """A finger palpating a surface: load-unload cycles at random levels and rates."""
    m = MATERIAL_MODELS[material]
    normal = np.zeros(n)
    impulses = np.zeros(n)
    i = int(trial_rng.integers(0, max(1, int(0.2 * fs))))
    while i < n:
        rate = np.exp(trial_rng.uniform(*np.log(p.press_rate_hz)))
        level = trial_rng.uniform(*p.press_force_n)
        length = max(4, int(fs / rate))
        contact = int(length * trial_rng.uniform(0.5, 0.9))
        seg = level * np.sin(np.pi * np.arange(contact) / contact) ** 2
        end = min(n, i + contact)
        normal[i:end] = seg[: end - i]
        impulses[i] += p.impact_n * m.hardness * np.sqrt(rate) * rng.lognormal(0, 0.4)
        i += length
    loading = np.maximum(np.gradient(normal) * fs, 0)
    crackle = p.crackle_n * (m.fibre_noise_gain + m.texture_gain) * np.sqrt(loading) * rng.standard_normal(n)
    ringing = _resonate(impulses, unit.resonance_hz * m.resonance_scale, m.damping, fs)
    shear = p.press_shear_ratio * normal + 0.5 * ringing + crackle
    return np.stack([shear, 0.2 * ringing, normal + ringing + crackle]), np.zeros(n, bool)


def _free_space_forces(n, fs, speed_avg, trial_rng, rng, unit, p: Physics):
    """No contact: fingertip inertia, drive vibration and start/stop jerks of the moving arm."""
    t = np.arange(n) / fs
    # motion segments between joint configurations; each starts and stops with a jerk
    seg_s = trial_rng.uniform(1.0, 3.0, int(n / fs) + 2)
    bounds = np.cumsum(seg_s) * fs
    bounds = bounds[bounds < n].astype(int)
    phase = np.interp(np.arange(n), np.r_[0, bounds, n], np.r_[0, np.arange(1, len(bounds) + 1), len(bounds) + 1])
    speed = speed_avg * (1 - np.cos(2 * np.pi * phase))
    accel = np.gradient(speed) * fs / 1000.0  # m/s^2
    rel = speed_avg / 25.0
    inertial = p.inertial_n * accel[None, :] * rng.normal(0, 1, (3, 1)) / max(np.abs(accel).max(), 1e-9) * rel
    impulses = np.zeros(n)
    impulses[bounds] = p.jerk_n * rel * rng.lognormal(0, 0.5, len(bounds))
    ringing = _resonate(impulses, unit.resonance_hz, 0.08, fs)
    gear_phase = 2 * np.pi * np.cumsum(p.gear_hz_per_mm_s * speed) / fs
    gear = p.gear_n * (speed / 25.0) * np.sin(gear_phase)
    vib = ringing + gear
    direction = rng.normal(0, 1, (3, 1))
    forces = inertial + direction / np.linalg.norm(direction) * vib
    return forces, np.zeros(n, bool)


def _sense(forces: np.ndarray, sensor: Sensor, unit: Unit, fs: float, rng, p: Physics) -> np.ndarray:
    """What the sensor reports: skin filtering, idle vibration, mixing, gain, noise; (n, channels)."""
    n = forces.shape[1]
    idle = sensor.idle_coupling * p.idle_n * np.sin(2 * np.pi * p.idle_hz * np.arange(n) / fs + rng.uniform(0, 2 * np.pi))
    forces = forces + idle * np.array([[0.5], [0.5], [1.0]])
    if unit.skin_cutoff_hz is not None:
        forces = _lowpass(forces, unit.skin_cutoff_hz, fs, axis=1)
    out = unit.mixing @ forces  # (channels, n)
    if sensor.highpass_hz is not None:
        out = signal.sosfilt(signal.butter(2, sensor.highpass_hz, "highpass", fs=fs, output="sos"), out, axis=1)
    out = out + rng.normal(0, sensor.noise_floor_n * unit.noise, out.shape)
    return (out.T * unit.gain * sensor.units_per_newton).astype(np.float32)


def generate(scale: float = 0.05, seed: int = 0, design: Design = Design()) -> tuple[pd.DataFrame, dict, dict]:
    """Simulate the design of experiments.

    Returns
    -------
    recordings : metadata DataFrame in the dataset format.
    samples : recording_id -> float32 (n_samples, n_channels).
    slip_labels : recording_id -> bool (n_samples,), True while the contact slides.
    """
    if not scale > 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    p = design.physics
    rows, samples, labels = [], {}, {}
    plan = [("slip", mat, v, design.slip_trials, design.slip_s_per_cell) for mat in design.materials for v in design.slip_speeds]
    plan += [("press", mat, None, design.press_trials, design.press_s_per_material) for mat in design.materials]
    plan += [("free-space", None, v, design.free_trials, design.free_s_per_speed) for v in design.free_speeds]
    for sensor_type in design.sensors:
        sensor = SENSORS[sensor_type]
        fs = sensor.rate_hz
        units = {inst: make_unit(seed, sensor_type, inst, p) for inst in sensor.instances}
        for scenario, material, speed, trials, seconds in plan:
            n = max(64, int(round(seconds * scale / trials * fs)))
            for trial in range(trials):
                for inst, unit in units.items():
                    trial_rng = _rng(seed, "trial", sensor_type, scenario, material, speed, trial)
                    rng = _rng(seed, "rec", sensor_type, inst, scenario, material, speed, trial)
                    if scenario == "slip":
                        forces, slip = _slip_forces(n, fs, speed, material, trial_rng, rng, unit, p)
                    elif scenario == "press":
                        forces, slip = _press_forces(n, fs, material, trial_rng, rng, unit, p)
                    else:
                        forces, slip = _free_space_forces(n, fs, speed, trial_rng, rng, unit, p)
                    rid = "-".join(
                        str(x) for x in (sensor_type, inst, scenario, material or "none",
                                         "none" if speed is None else f"{speed:g}", trial)
                    )
                    samples[rid] = _sense(forces, sensor, unit, fs, rng, p)
                    labels[rid] = slip
                    rows.append(dict(
                        recording_id=rid, sensor_type=sensor_type, sensor_instance=inst, scenario=scenario,
                        material=material, speed_mm_s=speed, sampling_rate_hz=fs,
                        channels=sensor.channels, units=(sensor.unit,) * len(sensor.channels),
                        source=f"slipbench.synth v{MODEL_VERSION} seed={seed} scale={scale:g}",
                    ))
    return pd.DataFrame(rows), samples, labels


def synthesize(out: str | Path, scale: float = 0.05, seed: int = 0, design: Design = Design()) -> Path:
    """Generate the simulated dataset into folder ``out`` (written atomically)."""
    recordings, samples, labels = generate(scale, seed, design)
    return write_dataset(out, recordings, samples, labels)


def with_physics(design: Design = Design(), **changes) -> Design:
    """A design whose physics differs in the named fields (for ablations and tests)."""
    return replace(design, physics=replace(design.physics, **changes))
