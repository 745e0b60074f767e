"""The embedded default dataset: a physical simulation of the paper's design of experiments.

Three sensor types (Nano17, OptoForce20, BioTac SP) on the fingers of a hand, five materials,
slip at four average speeds, pressing on each material (palpating it, lifting it, pushing it:
shear without slip, up to the friction cone), free-space motion at three speeds, and
continuous onset trials (``hold-slip``: contact held, then slip, sometimes a drop) for
streaming detection. The BioTac SP records its 24 electrodes beside the pac channel that the
paper's signal uses. Every effect is a field of :class:`Physics`, :class:`Sensor`,
:class:`ElectrodeArray` or :class:`Material` and is described, with where its value comes from,
in ``datasets.md`` and ``docs/explanation/simulation.md`` (the contact's mechanics, model version 4). The
model is physical and is *not* fitted to the paper's accuracies.

Variability is layered as in a real campaign: each unit differs from its nominal type (gain,
noise, the finger's share of the contact force, mass, finger stiffness, skin, mount); each
trial differs (grip force, surface state, arm motion), and is shared by the fingers recorded in
it (the ``trial`` column); each recording differs (contact patch, finger rolling, the spot of
surface it slides over, mounting drift).

All randomness flows from one seed. Each recording draws from its own streams, keyed by what it
is (sensor, instance, scenario, material, speed, trial), so the result does not depend on the
order of generation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.data.contact import annulus_travel, breakaway
from slipbench.data.synth_model import MODEL_VERSION
from slipbench.data.write import write_dataset
from slipbench.seeding import rng_for
from slipbench.vocabulary import FREE_SPACE_SPEEDS, MATERIALS, SENSOR_TYPE, SLIP_SPEEDS

UNLABELLED = -1  # per-sample label of samples whose slip state is undefined (after a drop)


@dataclass(frozen=True)
class ElectrodeArray:
    """Impedance electrodes on a fingertip's rigid core, under fluid and skin (BioTac SP).

    The skin presses the contact's load into the fluid: where the fluid gap over an electrode
    thins, its impedance changes. An electrode's change is the contact force pressed onto its
    face (the force along the face's normal, which tilts where the core curves over the tip and
    the flanks), weighted by the contact's pressure spread by skin and fluid (a Gaussian of the
    Hertz contact radius and ``spread_mm``) around where the contact sits. The tangential force
    also drags the skin, and the pressure with it, over the core (``skin_mm_per_n``). Both
    press the electrodes on the side the shear points to further and relieve those on the
    other side. Positions are (along the finger towards its tip, across) in mm; a face's tilts
    are towards +x and +y, in degrees.
    """

    names: tuple[str, ...]
    positions_mm: tuple[tuple[float, float], ...]
    tilts_deg: tuple[tuple[float, float], ...]
    counts_per_n: float  # change under the contact's centre per newton of normal force
    spread_mm: float  # how far skin and fluid spread a point load (sd)
    skin_mm_per_n: float  # the skin's tangential shift over the core per newton of shear
    centre_mm: tuple[float, float]  # where the hand's pose puts the contact, nominally
    rest_counts: tuple[float, float]  # resting offsets: mean and electrode-to-electrode sd
    full_scale: int  # the ADC's largest count (12 bits)
    noise_counts: float  # white noise sd, before rounding to whole counts
    band_hz: float  # each electrode is read 100 times a second: its band ends at 50 Hz
    gain_sd: float  # electrode-to-electrode sensitivity (log-normal sd)
    unit_centre_sd_mm: float  # the unit's mean contact position (the hand's pose)
    centre_sd_mm: float  # one recording's contact position (the finger rolling)
    drift_counts: float  # one recording's shift of every resting offset (temperature)

    @property
    def normals(self) -> np.ndarray:
        """(n_electrodes, 3) unit normals of the electrodes' faces: (along, across, normal)."""
        tan = np.tan(np.radians(np.asarray(self.tilts_deg)))
        faces = np.column_stack([tan, np.ones(len(tan))])
        return faces / np.linalg.norm(faces, axis=1, keepdims=True)


def _grid(rows: tuple[float, ...], columns: tuple[float, ...]) -> tuple[tuple[float, float], ...]:
    """Every (row, column) pair of a rows x columns layout, row by row."""
    return tuple((x, y) for x in rows for y in columns)


# 6 rows along the pad, 4 columns across it: flat under the pad, curving over the tip (the last
# two rows) and down the flanks (the outer columns)
_ROWS_MM, _ROW_TILTS = (-14.0, -10.0, -6.0, -2.0, 2.0, 6.0), (0.0, 0.0, 0.0, 0.0, 20.0, 45.0)
_COLUMNS_MM, _COLUMN_TILTS = (-6.0, -2.0, 2.0, 6.0), (-50.0, -10.0, 10.0, 50.0)
BIOTAC_SP_ELECTRODES = ElectrodeArray(
    names=tuple(f"e{k}" for k in range(1, 25)),
    positions_mm=_grid(_ROWS_MM, _COLUMNS_MM),
    tilts_deg=_grid(_ROW_TILTS, _COLUMN_TILTS),
    counts_per_n=150.0,
    spread_mm=2.5,
    skin_mm_per_n=1.0,
    centre_mm=(-4.0, 0.0),
    rest_counts=(3450.0, 250.0),
    full_scale=4095,
    noise_counts=2.0,
    band_hz=50.0,
    gain_sd=0.2,
    unit_centre_sd_mm=2.0,
    centre_sd_mm=1.0,
    drift_counts=5.0,
)


@dataclass(frozen=True)
class Sensor:
    """One sensor type: sampling, channels and its mechanics."""

    rate_hz: float
    instances: tuple[str, ...]
    channels: tuple[str, ...]
    unit: str
    units_per_newton: float
    noise_floor_n: float  # white noise std of the force estimate, in N (datasheet resolution)
    skin_cutoff_hz: float | None  # rubber skin as a mechanical low-pass; None: thin coating
    idle_coupling: float  # how much of the arm's idle vibration reaches the sensor
    tip_radius_mm: float  # radius of the touching surface (Hertz contact)
    tip_modulus_mpa: float  # plane-strain modulus E / (1 - nu^2) of what touches the surface
    tip_loss: float  # its loss factor (tan delta)
    mass_g: float  # sensor and fingertip, moving with the contact
    gain_sd: float  # unit-to-unit spread of sensitivity (log-normal sd)
    highpass_hz: float | None = None  # BioTac SP: the pressure channel (pac) is high-passed
    electrodes: ElectrodeArray | None = None  # recorded beside the channels above

    @property
    def recorded_channels(self) -> tuple[str, ...]:
        """Every channel a recording holds: the force channels, then any electrodes."""
        return self.channels + (self.electrodes.names if self.electrodes else ())

    @property
    def univariate_channels(self) -> tuple[str, ...]:
        """The channels the paper's signal s uses: the force channels where the sensor has
        electrodes besides (the BioTac SP's pac), else all (written as none: ())."""
        return self.channels if self.electrodes else ()


SENSORS: dict[str, Sensor] = {
    "Nano17": Sensor(
        1000.0,
        ("index", "middle", "little"),
        ("g1", "g2", "g3", "g4", "g5", "g6"),
        "N",
        1.0,
        0.006,
        None,
        1.0,
        8.0,
        2300.0,
        0.02,
        12.0,
        0.05,
    ),
    "OptoForce20": Sensor(
        1000.0,
        ("index", "middle", "little"),
        ("fx", "fy", "fz"),
        "count",
        400.0,
        0.0025,
        250.0,
        0.0,
        10.0,
        1.33,
        0.10,
        10.0,
        0.25,
    ),
    "BioTacSP": Sensor(
        850.0,
        ("index", "middle"),
        ("pac",),
        "count",
        100.0,
        0.010,
        250.0,
        0.8,
        7.5,
        0.40,
        0.30,
        30.0,
        0.25,
        10.0,
        BIOTAC_SP_ELECTRODES,
    ),
}


@dataclass(frozen=True)
class Material:
    """Mechanics and tribology of one surface."""

    modulus_mpa: float  # plane-strain modulus E / (1 - nu^2), normal to the sheet
    loss: float  # loss factor (tan delta)
    critical_slip_mm: float  # mean sliding distance between two stick-slip snaps
    snap_gain: float  # relative size of the force drop at a snap
    smear_hz: float | None  # soft surfaces smear snaps: low-pass on the event train
    texture_period_mm: float  # spatial period of the surface (grain, corrugation, brushing)
    texture_gain: float
    fibre_noise_gain: float  # broadband rubbing noise (cardboard fibres)
    hardness: float  # impact transient when a finger lands on it while pressing
    friction: float  # kinetic Coulomb coefficient of a fingertip's elastomer sliding on it


MATERIAL_MODELS: dict[str, Material] = {
    "aluminum": Material(77000.0, 0.001, 0.4, 1.0, None, 0.08, 0.10, 0.0, 1.0, 0.6),
    "PVC": Material(3600.0, 0.03, 0.5, 0.8, None, 0.25, 0.15, 0.0, 0.8, 0.5),
    "neoprene": Material(4.0, 0.20, 1.5, 0.35, 30.0, 1.00, 0.10, 0.0, 0.2, 0.9),
    "cardboard": Material(30.0, 0.08, 0.6, 0.6, None, 0.80, 0.30, 0.5, 0.5, 0.45),
    "plywood": Material(800.0, 0.03, 0.5, 0.8, None, 1.60, 0.60, 0.1, 0.7, 0.5),
}

#: what a finger does in a ``press`` recording, one task per trial (``Physics.press_tasks``)
PRESS_TASKS = ("palpate", "lift", "push")


@dataclass(frozen=True)
class Physics:
    """Every effect of the simulation, with its size. Forces are in newtons."""

    path_mm: float = 180.0  # back-and-forth drag path; speed ramps 0 -> 2 x average -> 0 per pass
    stick_speed_mm_s: float = 0.5  # below this the contact sticks: no snaps, slip label off
    normal_force_n: tuple[float, float] = (0.5, 2.0)  # range of per-trial contact force
    arm_oscillation_hz: tuple[float, float] = (1.0, 3.0)  # natural oscillation of the moving arm
    arm_oscillation_depth: float = 0.15  # relative normal-force modulation while dragging
    static_friction_ratio: float = 1.25  # static / kinetic friction of a rubber contact
    friction_trial_sd: float = 0.15  # the surface's friction in a trial (dust, humidity, wear)
    friction_local_sd: float = 0.05  # the spot of surface one finger touches
    snap_n_per_n: float = 0.03  # snap force drop per newton of normal force at 25 mm/s
    snap_speed_exponent: float = 0.5  # snap size grows with local speed as (v / 25 mm/s)^k
    texture_n_per_n: float = 0.01  # texture force per newton of normal force
    fibre_noise_n: float = 0.008  # rubbing noise at fibre gain 1 and 25 mm/s
    finger_stiffness_n_mm: float = 10.0  # the finger's structure, in series with the contact
    finger_mass_g: float = 30.0  # the share of the distal link that moves with the fingertip
    finger_loss: float = 0.1  # loss factor of the finger's structure
    idle_hz: float = 200.0  # the arm's idling vibration
    idle_n: float = 0.008
    press_force_n: tuple[float, float] = (0.2, 4.0)  # pressing force levels (palpation, grip)
    press_rate_hz: tuple[float, float] = (0.1, 4.0)  # palpation frequencies
    press_tilt_deg: tuple[float, float] = (0.0, 35.0)  # palpating finger's axis to the normal
    # loaded contact without slip: shares of the press tasks (PRESS_TASKS) among recordings
    press_tasks: tuple[float, float, float] = (1.0, 1.0, 1.0)
    safety_margin: tuple[float, float] = (1.1, 1.7)  # grip over the least that holds the load
    episode_s: tuple[float, float] = (1.0, 4.0)  # one lift or push, grasp to release
    transport_speed_mm_s: tuple[float, float] = (25.0, 75.0)  # the arm carrying a lifted object
    push_speed_mm_s: tuple[float, float] = (5.0, 25.0)  # the arm pushing an object along
    impact_n: float = 0.02  # impact transient at hardness 1 and a 1 Hz palpation
    crackle_n: float = 0.004  # fibres and grain crushing under load (cardboard, plywood)
    inertial_n: float = 0.004  # fingertip inertia under free-space arm motion at 25 mm/s
    jerk_n: float = 0.02  # transient when a free-space motion segment starts or stops
    gear_hz_per_mm_s: float = 1.2  # drive vibration tone: frequency per mm/s of arm speed
    gear_n: float = 0.003  # its size at 25 mm/s
    # unit to unit (log-normal sd; the sensor type's own gain spread is Sensor.gain_sd)
    unit_spread: float = 1.0  # multiplies every unit spread below and gain_sd (0: identical units)
    unit_force_sd: float = 0.50  # the finger's share of the contact force, set by the hand pose
    unit_coupling_sd: float = 0.30  # where the fixed pose puts the contact on the fingertip
    unit_noise_sd: float = 0.30  # noise floor (cabling, electronics)
    unit_mass_sd: float = 0.10  # moving mass (fingertip adapter, screws)
    unit_finger_sd: float = 0.20  # the finger's structural stiffness (gear play, link)
    unit_skin_sd: float = 0.20  # skin modulus and its low-pass cut-off (hardness tolerance)
    unit_idle_sd: float = 0.50  # how the mount passes the arm's vibration
    # trial and recording signatures (log-normal sd)
    signature_spread: float = 1.0  # multiplies every signature spread below (0: none)
    surface_trial_sd: float = 0.25  # the surface's state in a trial: snap spacing and size
    surface_local_sd: float = 0.15  # the spot of surface one finger slides over
    patch_gain_sd: float = 0.15  # where the contact patch sits on the fingertip
    force_wobble_sd: float = 0.15  # the finger's rolling and twisting: its force in a recording
    drift_gain_sd: float = 0.05  # mounting and thermal drift of the sensitivity over a session
    roll_tilt_deg: float = 5.0  # the finger rolling about a millimetre on its rounded tip (deg)
    heading_sd_deg: float = 15.0  # the shear's heading on the pad off the finger's axis (deg)
    # onset trials (hold, then slip, sometimes a drop)
    hold_s: tuple[float, float] = (0.5, 1.5)  # contact held still before the arm moves
    ramp_s: float = 0.3  # the arm accelerates to the trial's speed in this time
    tangential_stiffness_n_mm: float = 0.3  # the finger's shear compliance before breakaway
    hold_fluctuation: float = 0.05  # slow grip-force fluctuation while holding
    grip_adjust_rate_hz: float = 0.5  # small pressing-like grip adjustments
    grip_adjust_depth: float = 0.10
    precursor_gain: float = 0.15  # a micro-slip at the contact's edge, relative to a full snap
    annulus_step: float = 0.05  # mean sweep of the slip annulus (area fraction) per micro-slip
    drop_fraction: float = 0.3  # share of onset trials that end in losing the contact
    drop_after_s: tuple[float, float] = (0.5, 1.5)  # slip time before the drop
    drop_fall_s: float = 0.03  # the contact force falls to zero in this time
    release_n_per_n: float = 0.05  # spring-back transient of the finger at release


@dataclass(frozen=True)
class Design:
    """How much of each scenario, in seconds per sensor instance at scale 1.0 (~8 M samples of
    the paper's design plus ~4 M of onset trials and long non-slip recordings)."""

    slip_s_per_cell: float = 200.0  # per material x speed: 20 cells, half the paper's data
    press_s_per_material: float = 400.0  # a quarter of the paper's data
    free_s_per_speed: float = 2000.0 / 3  # a quarter of the paper's data
    slip_trials: int = 8  # recordings per material x speed
    press_trials: int = 8  # recordings per material
    free_trials: int = 12  # recordings per speed (joint-configuration sequences)
    onset_s_per_cell: float = 120.0  # hold-slip trials per material x speed
    onset_recording_s: float = 6.0  # nominal length of one onset trial
    long_press_s_per_material: float = 200.0  # long continuous pressing, for false alarms
    long_free_s_per_speed: float = 200.0  # long continuous free-space motion
    long_recording_s: float = 10.0
    materials: tuple[str, ...] = MATERIALS
    slip_speeds: tuple[float, ...] = SLIP_SPEEDS
    free_speeds: tuple[float, ...] = FREE_SPACE_SPEEDS
    sensors: tuple[str, ...] = tuple(SENSORS)
    physics: Physics = field(default_factory=Physics)


def _spread(rng: np.random.Generator, sd: float, size: int | None = None):
    """Log-normal factor(s) with median 1."""
    return np.exp(rng.normal(0.0, sd, size))


@dataclass(frozen=True)
class Unit:
    """One physical sensor on one finger: how it differs from its nominal type."""

    gain: float
    noise: float
    force_share: float  # the finger's contact force relative to the trial's grip level
    coupling: (
        float  # how much of the contact force reaches the transducer (contact location, lever arm)
    )
    mass_kg: float  # sensor, fingertip and the distal link's moving share
    finger_stiffness_n_m: float
    tip_modulus_pa: float
    skin_cutoff_hz: float | None
    idle_coupling: float
    mixing: np.ndarray  # (n_channels, 3): force -> channels
    electrodes: ElectrodeUnit | None = None


@dataclass(frozen=True)
class ElectrodeUnit:
    """How one unit's electrodes differ from their nominal array."""

    rest: np.ndarray  # (n_electrodes,) resting counts
    gain: np.ndarray  # (n_electrodes,) sensitivity factors
    centre_mm: np.ndarray  # (2,) where this unit's contact sits


def _electrode_unit(
    seed: int, sensor_type: str, instance: str, array: ElectrodeArray, p: Physics
) -> ElectrodeUnit:
    """Draw a unit's electrodes from their own stream (the unit's other draws stay as they were)."""
    rng = rng_for(seed, "electrode-unit", sensor_type, instance)
    n, k = len(array.names), p.unit_spread
    mean, sd = array.rest_counts
    rest = np.clip(rng.normal(mean, sd * k, n), 0.5 * mean, 0.95 * array.full_scale)
    return ElectrodeUnit(
        rest=np.round(rest),
        gain=_spread(rng, array.gain_sd * k, n),
        centre_mm=np.array(array.centre_mm) + rng.normal(0, array.unit_centre_sd_mm * k, 2),
    )


def make_unit(seed: int, sensor_type: str, instance: str, physics: Physics) -> Unit:
    """Draw one unit of ``sensor_type`` mounted on finger ``instance`` (its own keyed stream)."""
    s, p = SENSORS[sensor_type], physics
    rng = rng_for(seed, "unit", sensor_type, instance)
    k = p.unit_spread
    gain = float(_spread(rng, s.gain_sd * k))
    noise = float(_spread(rng, p.unit_noise_sd * k))
    force_share = float(_spread(rng, p.unit_force_sd * k))
    coupling = float(_spread(rng, p.unit_coupling_sd * k))
    mass = (s.mass_g + p.finger_mass_g) * 1e-3 * float(_spread(rng, p.unit_mass_sd * k))
    finger = p.finger_stiffness_n_mm * 1e3 * float(_spread(rng, p.unit_finger_sd * k))
    skin = float(_spread(rng, p.unit_skin_sd * k))
    # a harder skin (higher modulus) passes higher frequencies: both move together
    modulus = s.tip_modulus_mpa * 1e6 * (skin if s.skin_cutoff_hz is not None else 1.0)
    cutoff = None if s.skin_cutoff_hz is None else s.skin_cutoff_hz * skin
    idle = s.idle_coupling * float(_spread(rng, p.unit_idle_sd * k))
    n = len(s.channels)
    if n == 3:
        mixing = np.eye(3) + rng.normal(0, 0.03 * k, (3, 3))  # cross-talk of an optical 3-axis cell
    elif n == 1:
        # fluid pressure: mostly normal load; how much shear reaches it depends on the fit
        mixing = np.array([[*np.abs(rng.normal(0.3, 0.1 * k, 2)), 1.0]])
    else:
        # strain gauges: a well-conditioned calibration matrix, normalised so that
        # ||mixing @ f|| ~ ||f|| and the noise floor keeps its meaning in newtons
        q, _ = np.linalg.qr(rng.normal(size=(n, 3)))
        mixing = q * _spread(rng, 0.05 * k, 3)
    electrodes = (
        None
        if s.electrodes is None
        else _electrode_unit(seed, sensor_type, instance, s.electrodes, p)
    )
    return Unit(
        gain, noise, force_share, coupling, mass, finger, modulus, cutoff, idle, mixing, electrodes
    )


def _tilt(rng: np.random.Generator, sd_deg: float) -> np.ndarray:
    """A rotation (3, 3) that tilts the contact's normal off the sensor's axis by a 2-D normal
    draw of ``sd_deg`` per axis (a contact off the apex of a rounded tip), about an axis in
    the tangent plane (Rodrigues' formula)."""
    tx, ty = np.radians(rng.normal(0.0, sd_deg, 2))
    angle = np.hypot(tx, ty)
    if angle == 0.0:
        return np.eye(3)
    axis = np.array([-ty, tx, 0.0]) / angle
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


@dataclass(frozen=True)
class Signature:
    """What makes one recording differ from another of the same unit and trial."""

    patch: float  # coupling of the contact patch's position on the fingertip
    force: float  # the finger's force in this recording relative to its share (rolling, twist)
    spacing: float  # local factor on the stick-slip critical distance
    snap: float  # local factor on the snap size
    drift: float  # mounting and thermal drift of the sensitivity
    friction: float  # factor on the material's friction: the trial's surface, the local spot
    roll: np.ndarray  # (3, 3) the finger rolling: the contact's normal tilts a little further
    heading: float  # radians: where the shear points on the pad, off the finger's axis


def _signature(rng: np.random.Generator, trial_rng: np.random.Generator, p: Physics) -> Signature:
    """Draw a recording's signature; the surface state of the trial is shared by its fingers."""
    k = p.signature_spread
    trial_spacing, trial_snap = _spread(trial_rng, p.surface_trial_sd * k, 2)
    local_spacing, local_snap = _spread(rng, p.surface_local_sd * k, 2)
    return Signature(
        patch=float(_spread(rng, p.patch_gain_sd * k)),
        force=float(_spread(rng, p.force_wobble_sd * k)),
        spacing=float(trial_spacing * local_spacing),
        snap=float(trial_snap * local_snap),
        drift=float(_spread(rng, p.drift_gain_sd * k)),
        friction=float(
            _spread(trial_rng, p.friction_trial_sd * k) * _spread(rng, p.friction_local_sd * k)
        ),
        roll=_tilt(rng, p.roll_tilt_deg * k),
        heading=float(np.radians(rng.normal(0.0, p.heading_sd_deg * k))),
    )


def contact_mode(
    sensor: Sensor, unit: Unit, material: str, normal_n: float, p: Physics
) -> tuple[float, float]:
    """Frequency (Hz) and damping ratio of the fingertip's ringing mode while touching.

    A lumped one-mode model: the moving mass (sensor, fingertip, the distal link's share) on the
    contact stiffness in series with the finger's structural stiffness. The contact stiffness is
    Hertz's, k = (6 E*^2 R F)^(1/3), with E* the series combination of the tip's and the
    surface's plane-strain moduli, so soft surfaces and light forces ring lower. The damping
    ratio is half the compliance-weighted loss factor of the three elements.
    """
    m = MATERIAL_MODELS[material]
    c_tip, c_surface = 1.0 / unit.tip_modulus_pa, 1.0 / (m.modulus_mpa * 1e6)
    e_star = 1.0 / (c_tip + c_surface)
    k_contact = (6.0 * e_star**2 * sensor.tip_radius_mm * 1e-3 * max(normal_n, 0.05)) ** (1 / 3)
    c_contact, c_finger = 1.0 / k_contact, 1.0 / unit.finger_stiffness_n_m
    compliance = c_contact + c_finger
    contact_loss = (sensor.tip_loss * c_tip + m.loss * c_surface) / (c_tip + c_surface)
    zeta = 0.5 * (contact_loss * c_contact + p.finger_loss * c_finger) / compliance
    return float(np.sqrt(1.0 / (compliance * unit.mass_kg)) / (2 * np.pi)), float(zeta)


def free_mode(unit: Unit, p: Physics) -> tuple[float, float]:
    """Frequency (Hz) and damping ratio of the fingertip's mode without contact."""
    return float(
        np.sqrt(unit.finger_stiffness_n_m / unit.mass_kg) / (2 * np.pi)
    ), 0.5 * p.finger_loss


def _resonate(impulses: np.ndarray, f0: float, damping: float, fs: float) -> np.ndarray:
    """Ring a damped oscillator at f0 with each impulse (a 2-pole IIR resonator)."""
    w = 2 * np.pi * min(f0, 0.45 * fs) / fs
    r = np.exp(-damping * w)
    from scipy import signal  # here, not at import: reading the cached dataset needs no filter

    return signal.lfilter([np.sin(w)], [1.0, -2 * r * np.cos(w), r * r], impulses)


@lru_cache(maxsize=256)
def _butter(order: int, cutoff: float, fs: float, kind: str = "lowpass") -> np.ndarray:
    """A Butterworth filter's sections; designed once per unit, material and rate (the design
    took 40 % of the generation time when every recording redid it)."""
    from scipy import signal

    return signal.butter(order, cutoff, kind, fs=fs, output="sos")


def _filtered(sos: np.ndarray, x: np.ndarray, axis: int = -1) -> np.ndarray:
    from scipy import signal

    return signal.sosfilt(sos, x, axis=axis)


def _lowpass(x: np.ndarray, cutoff: float, fs: float, order: int = 2, axis: int = -1) -> np.ndarray:
    if cutoff >= 0.49 * fs:
        return x
    return _filtered(_butter(order, cutoff, fs), x, axis=axis)


def _events(distance_mm: np.ndarray, mean_spacing: float, rng: np.random.Generator) -> np.ndarray:
    """Positions (mm of travel) of stick-slip snaps: gamma-spaced with the given mean."""
    total = float(distance_mm[-1])
    n_max = int(total / mean_spacing * 1.5) + 16
    pos = np.cumsum(rng.gamma(4.0, mean_spacing / 4.0, n_max))
    return pos[pos < total]


def _snaps(
    take: Take, speed: np.ndarray, sliding: np.ndarray, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stick-slip of a sliding contact: snap impulses, the shear sawtooth between snaps, travel.

    Each time the travel since the last snap reaches a gamma-spread critical distance, the shear
    drops by a snap; between snaps it builds up again. Returns arrays of shape (n,).
    """
    m, sig, fs, rng, p = take.surface, take.sig, take.fs, take.rng, take.p
    travel = np.cumsum(np.where(sliding, speed, 0.0)) / fs
    spacing = m.critical_slip_mm * sig.spacing
    rel = (np.maximum(speed, 1e-9) / 25.0) ** p.snap_speed_exponent
    drop = (
        p.snap_n_per_n * m.snap_gain * sig.snap * normal * rel
    )  # force drop a snap would give now
    impulses = np.zeros(len(speed))
    if travel[-1] > 0:
        pos = _events(travel, spacing, rng)
        idx = np.searchsorted(travel, pos)
        np.add.at(impulses, idx, drop[idx] * rng.lognormal(0, 0.3, len(idx)))
        last = np.searchsorted(pos, travel, side="right") - 1
        since = travel - np.r_[0.0, pos][last + 1]
    else:
        since = np.zeros(len(speed))
    saw = drop * (np.clip(since / spacing, 0, 1.5) - 0.5) * sliding
    return impulses, saw, travel


def _surface(
    take: Take, travel: np.ndarray, speed: np.ndarray, sliding: np.ndarray, normal: np.ndarray
) -> np.ndarray:
    """Texture tone at speed / spatial period and fibrous rubbing noise of a sliding contact."""
    m, rng, p = take.surface, take.rng, take.p
    texture = (
        p.texture_n_per_n
        * m.texture_gain
        * normal
        * np.sin(2 * np.pi * travel / m.texture_period_mm + rng.uniform(0, 2 * np.pi))
    )
    fibre = (
        p.fibre_noise_n
        * m.fibre_noise_gain
        * np.sqrt(np.maximum(speed, 0) / 25.0)
        * rng.standard_normal(len(speed))
    )
    return (texture + fibre) * sliding


def _drive(speed: np.ndarray, fs: float, p: Physics) -> np.ndarray:
    """The arm's drive tone, whose frequency follows its speed."""
    phase = 2 * np.pi * np.cumsum(p.gear_hz_per_mm_s * speed) / fs
    return p.gear_n * (speed / 25.0) * np.sin(phase)


@dataclass(frozen=True)
class Take:
    """What one simulated recording is made from: its length and rate, the cell (material,
    speed), the unit and the recording's signature, its random streams and the physics."""

    n: int
    fs: float
    material: str | None
    speed: float | None
    sensor: Sensor
    unit: Unit
    sig: Signature
    trial_rng: np.random.Generator  # draws shared by the fingers recorded in the trial
    rng: np.random.Generator  # the recording's own draws
    p: Physics

    @property
    def surface(self) -> Material:
        return MATERIAL_MODELS[str(self.material)]

    @property
    def arm_speed(self) -> float:
        """The cell's speed (mm/s): of slip, onset trials and free-space motion."""
        if self.speed is None:
            raise ValueError("a scenario without a speed has no arm speed")
        return self.speed

    @property
    def mu_kinetic(self) -> float:
        """The surface's kinetic friction in this trial, on this spot."""
        return self.surface.friction * self.sig.friction

    @property
    def mu_static(self) -> float:
        return self.p.static_friction_ratio * self.mu_kinetic

    def on_pad(self, along: np.ndarray, across: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Forces (3, n) on the pad from the shear along the load's heading and across it, and
        the normal load: the heading is the finger's axis turned by ``sig.heading``."""
        c, s = np.cos(self.sig.heading), np.sin(self.sig.heading)
        return np.stack([c * along - s * across, s * along + c * across, normal])

    def draw_normal(self) -> float:
        """Draw the trial's normal force from its range, as this finger shares it here."""
        share = self.unit.force_share * self.sig.force
        return self.trial_rng.uniform(*self.p.normal_force_n) * share


def _edge_slips(take: Take, shear: np.ndarray, normal: np.ndarray, stuck: np.ndarray):
    """Impulses (n,) of the micro-slips at the contact's edge while its slip annulus sweeps
    (:func:`~slipbench.data.contact.annulus_travel`) where the contact still sticks as a whole
    (``stuck``): one per ``annulus_step`` of the annulus's area, gamma-spread, each
    ``precursor_gain`` of a full snap. Incipient slip, labelled 0."""
    p, m = take.p, take.surface
    swept = np.diff(annulus_travel(shear, normal, take.mu_static)) * stuck[1:]
    travel = np.r_[0.0, np.cumsum(swept)]
    impulses = np.zeros(len(shear))
    if travel[-1] > 0:
        idx = np.searchsorted(travel, _events(travel, p.annulus_step, take.rng))
        size = p.precursor_gain * p.snap_n_per_n * m.snap_gain * take.sig.snap * normal[idx]
        np.add.at(impulses, idx, size * take.rng.lognormal(0, 0.3, len(idx)))
    return impulses


def _slip_forces(take: Take) -> tuple[np.ndarray, np.ndarray]:
    """Contact forces (3, n) of the finger dragged back and forth across a surface, and the
    per-sample label: 1 while the contact slides; 0 while it sticks, from each reversal of the
    arm (the finger bends through the friction cone, the slip annulus at its edge growing)
    until it breaks away, and where the arm stands still at the path's ends."""
    n, fs, p, rng, m = take.n, take.fs, take.p, take.rng, take.surface
    t = np.arange(n) / fs
    pass_s = p.path_mm / take.arm_speed  # one leg of the path, there or back
    tt = t + take.trial_rng.uniform(0, pass_s)
    leg = (tt // pass_s).astype(int)
    phase = 2 * np.pi * (tt / pass_s - leg)
    speed = take.arm_speed * (1 - np.cos(phase))  # mm/s, its mean the cell's speed
    pulled = take.arm_speed * pass_s * (phase - np.sin(phase)) / (2 * np.pi)  # mm this leg
    direction = np.where(leg % 2 == 0, 1.0, -1.0)
    normal0 = take.draw_normal()
    osc = take.trial_rng.uniform(*p.arm_oscillation_hz)
    normal = normal0 * (
        1 + p.arm_oscillation_depth * np.sin(2 * np.pi * osc * t + rng.uniform(0, 2 * np.pi))
    )
    # each leg the finger bends from the last leg's kinetic shear, reversed, until breakaway
    loading = p.tangential_stiffness_n_mm * pulled - take.mu_kinetic * normal0
    broke = breakaway(loading, take.mu_static * normal, leg)
    sliding = broke & (speed > p.stick_speed_mm_s)

    f0, zeta = contact_mode(take.sensor, take.unit, str(take.material), normal0, p)
    impulses, saw, travel = _snaps(take, speed, sliding, normal)
    onsets = np.flatnonzero(np.diff(broke.astype(np.int8)) > 0) + 1
    impulses[onsets] += (take.mu_static - take.mu_kinetic) * normal[onsets]  # static -> kinetic
    held = np.where(broke, take.mu_kinetic * normal + saw, loading)
    impulses += _edge_slips(take, held, normal, ~broke)
    if m.smear_hz:
        impulses = _lowpass(impulses, m.smear_hz, fs, order=1)
    ringing = _resonate(impulses, f0, zeta, fs)
    vib = ringing + _surface(take, travel, speed, sliding, normal)
    across = 0.3 * vib * rng.choice([-1, 1])
    contact = take.on_pad(direction * held + vib, across, normal + 0.5 * ringing)
    return contact * take.unit.coupling * take.sig.patch + _unit_vector(rng) * _drive(
        speed, fs, p
    ), sliding.astype(np.int8)


def _held_grip(take: Take, t: np.ndarray) -> np.ndarray:
    """The relative grip (n,) of a held contact: a slow fluctuation plus small pressing-like
    adjustments (raised-cosine bumps)."""
    p, rng = take.p, take.rng
    grip = 1 + p.hold_fluctuation * np.sin(
        2 * np.pi * rng.uniform(0.3, 1.0) * t + rng.uniform(0, 2 * np.pi)
    )
    count = int(take.n / take.fs * p.grip_adjust_rate_hz * 3) + 2
    for start in np.cumsum(rng.exponential(1 / p.grip_adjust_rate_hz, count)):
        width = rng.uniform(0.2, 0.6)
        inside = (t >= start) & (t < start + width)
        grip[inside] += (
            p.grip_adjust_depth
            * rng.uniform(0.3, 1.0)
            * np.sin(np.pi * (t[inside] - start) / width) ** 2
        )
    return grip


def _drop(take: Take, lost: int, normal0: float) -> tuple[np.ndarray, np.ndarray]:
    """Losing the contact at sample ``lost``: the contact's share of the forces (n,), falling
    to zero in ``drop_fall_s``, and the finger's spring-back impulse (n,) once it is free."""
    n, p = take.n, take.p
    contact, release = np.ones(n), np.zeros(n)
    if lost < n:
        fall = max(1, int(round(p.drop_fall_s * take.fs)))
        contact[lost:] = 0.0
        contact[lost : lost + fall] = (
            1 + np.cos(np.pi * np.arange(min(fall, n - lost)) / fall)
        ) / 2
        release[min(lost + fall, n - 1)] = p.release_n_per_n * normal0
    return contact, release


def _hold_slip_forces(take: Take) -> tuple[np.ndarray, np.ndarray]:
    """An onset trial: the contact is held, the arm starts to pull, the shear loads the finger
    until it exceeds static friction (breakaway: slip onset, with a first large snap), then the
    contact slides with stick-slip; in some trials the contact is then lost (a drop).

    Returns forces (3, n) and the per-sample label: 0 before the onset, 1 from it, and
    ``UNLABELLED`` from the moment the contact force starts to fall in a drop.
    """
    n, fs, p, rng, m, trial_rng = take.n, take.fs, take.p, take.rng, take.surface, take.trial_rng
    t = np.arange(n) / fs
    hold = min(trial_rng.uniform(*p.hold_s), 0.3 * n / fs)
    normal0 = take.draw_normal()
    drops = trial_rng.random() < p.drop_fraction
    drop_after = trial_rng.uniform(*p.drop_after_s)
    osc = trial_rng.uniform(*p.arm_oscillation_hz)
    grip = _held_grip(take, t)
    # the arm's speed rises smoothly to the target; its oscillation grows with it
    moving = (1 - np.cos(np.pi * np.clip((t - hold) / p.ramp_s, 0, 1))) / 2
    speed = take.arm_speed * moving
    normal = normal0 * grip * (1 + p.arm_oscillation_depth * moving * np.sin(2 * np.pi * osc * t))

    # stick: the finger bends with the arm until the shear reaches static friction
    loading = p.tangential_stiffness_n_mm * np.cumsum(speed) / fs
    broke = np.flatnonzero(loading >= take.mu_static * normal)
    onset = int(broke[0]) if len(broke) else n
    after = np.arange(n) >= onset
    sliding = after & (speed > p.stick_speed_mm_s)

    f0, zeta = contact_mode(take.sensor, take.unit, str(take.material), normal0, p)
    impulses, saw, travel = _snaps(take, speed, sliding, normal)
    if onset < n:  # breakaway: the shear falls from static to kinetic friction at once
        impulses[onset] += (take.mu_static - take.mu_kinetic) * normal[onset]
    held = np.where(after, take.mu_kinetic * normal + saw, loading)
    impulses += _edge_slips(take, held, normal, ~after)
    if m.smear_hz:
        impulses = _lowpass(impulses, m.smear_hz, fs, order=1)
    ringing = _resonate(impulses, f0, zeta, fs)
    vib = ringing + _surface(take, travel, speed, sliding, normal)

    label = after.astype(np.int8)
    lost = onset + int(round(drop_after * fs)) if drops else n
    label[lost:] = UNLABELLED
    contact, release = _drop(take, lost, normal0)
    forces = take.on_pad(held + vib, 0.3 * vib * rng.choice([-1, 1]), normal + 0.5 * ringing)
    forces = forces * contact * take.unit.coupling * take.sig.patch
    spring_back = _resonate(release, *free_mode(take.unit, p), fs)
    return forces + _unit_vector(rng) * (_drive(speed, fs, p) + spring_back), label


@dataclass(frozen=True)
class Loads:
    """What a press task puts on the contact, (n,) each: normal load and shear (N), the arm's
    speed (mm/s); and each landing of the finger, (sample, rate in Hz: how brisk it is)."""

    normal: np.ndarray
    shear: np.ndarray
    speed: np.ndarray
    landings: list[tuple[int, float]]


def _palpate(take: Take) -> Loads:
    """Load-unload cycles at random levels and rates, the finger pressing along its own axis
    tilted from the surface's normal: shear and load grow in proportion, inside the cone."""
    n, fs, p, trial_rng = take.n, take.fs, take.p, take.trial_rng
    tilt = np.tan(np.radians(trial_rng.uniform(*p.press_tilt_deg)))
    ratio = min(tilt, take.mu_static / p.safety_margin[0])  # steeper, and it would slide
    share = take.unit.force_share * take.sig.force
    normal = np.zeros(n)
    landings = []
    i = int(trial_rng.integers(0, max(1, int(0.2 * fs))))
    while i < n:
        rate = np.exp(trial_rng.uniform(*np.log(p.press_rate_hz)))
        level = trial_rng.uniform(*p.press_force_n) * share
        length = max(4, int(fs / rate))
        contact = int(length * trial_rng.uniform(0.5, 0.9))
        seg = level * np.sin(np.pi * np.arange(contact) / contact) ** 2
        end = min(n, i + contact)
        normal[i:end] = seg[: end - i]
        landings.append((i, rate))
        i += length
    return Loads(normal, ratio * normal, np.zeros(n), landings)


def _knots(t: np.ndarray, at: np.ndarray, values: np.ndarray) -> np.ndarray:
    """A profile through the points (at, values), raised-cosine between two, flat outside."""
    j = np.clip(np.searchsorted(at, t, side="right") - 1, 0, len(at) - 2)
    u = np.clip((t - at[j]) / np.maximum(at[j + 1] - at[j], 1e-12), 0.0, 1.0)
    return values[j] + (values[j + 1] - values[j]) * (1 - np.cos(np.pi * u)) / 2


def _episode(take: Take, push: bool) -> tuple[np.ndarray, ...]:
    """One grasp, load, carry, unload and release: normal load, shear and arm speed, each of
    the episode's length (its phases those of a lift, Johansson & Westling 1984)."""
    p, trial_rng = take.p, take.trial_rng
    d = trial_rng.uniform(*p.episode_s)
    grip = trial_rng.uniform(*p.press_force_n) * take.unit.force_share * take.sig.force
    load = grip * take.mu_static / trial_rng.uniform(*p.safety_margin)
    v = trial_rng.uniform(*(p.push_speed_mm_s if push else p.transport_speed_mm_s))
    # pushing, the finger bends as the arm sets off, until the object breaks free of the table
    rise = min(load / (p.tangential_stiffness_n_mm * v * d), 0.4) if push else 0.0
    t = np.arange(int(d * take.fs)) / take.fs
    at = d * np.array([0.0, 0.1, 0.25, 0.25 + rise, 0.75, 0.9, 1.0])
    grips = _knots(t, at, grip * np.array([0.0, 0.3, 1.0, 1.0, 1.0, 0.3, 0.0]))
    loads = _knots(t, at, load * np.array([0.0, 0.0, float(not push), 1.0, 1.0, 0.0, 0.0]))
    if push:
        return grips, loads, _knots(t, at, v * np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]))
    # lifted: the arm carries it up and back, its accelerations adding to the weight
    u = np.clip((t - at[2]) / (at[4] - at[2]), 0.0, 1.0)
    moving = v * (1 - np.cos(2 * np.pi * u))
    return grips, loads * (1 + np.gradient(moving, t) / 1000.0 / 9.81), moving


def _carry(take: Take, push: bool) -> Loads:
    """Lifting against gravity or pushing along, episode after episode with no contact
    between: the grip closes, then the load comes on, the shear staying a safety margin
    inside the cone (lifting, load and grip rise together)."""
    n, fs = take.n, take.fs
    normal, shear, speed = np.zeros(n), np.zeros(n), np.zeros(n)
    landings = []
    i = -int(take.trial_rng.uniform(0, take.p.episode_s[1]) * fs)  # it may begin in one
    while i < n:
        episode = _episode(take, push)
        size = len(episode[0])
        lo, hi = max(i, 0), min(i + size, n)
        if hi > lo:
            normal[lo:hi], shear[lo:hi], speed[lo:hi] = (x[lo - i : hi - i] for x in episode)
        if i >= 0:
            landings.append((i, fs / size))
        i += size + int(take.trial_rng.uniform(0.1, 0.5) * fs)
    return Loads(normal, shear, speed, landings)


def _press_forces(take: Take) -> tuple[np.ndarray, np.ndarray]:
    """A finger loading a surface without slipping, one task per trial (``PRESS_TASKS``, in
    the shares ``press_tasks``): palpating it, lifting it against gravity, pushing it along.
    The shear stays inside the friction cone; where it outpaces the normal load, the slip
    annulus at the contact's edge sweeps and micro-slips ring (incipient slip, labelled 0)."""
    n, fs, p, rng, m = take.n, take.fs, take.p, take.rng, take.surface
    shares = np.asarray(p.press_tasks) / sum(p.press_tasks)
    task = PRESS_TASKS[int(take.trial_rng.choice(len(PRESS_TASKS), p=shares))]
    # along the finger, as the arm drags it in slip: the plane it curls, presses and pushes in
    sign = take.trial_rng.choice([-1.0, 1.0])
    loads = _palpate(take) if task == "palpate" else _carry(take, push=task == "push")
    normal = loads.normal
    impulses = np.zeros(n)
    for i, rate in loads.landings:
        impulses[i] += p.impact_n * m.hardness * np.sqrt(rate) * rng.lognormal(0, 0.4)
    impulses += _edge_slips(take, loads.shear, normal, np.ones(n, bool))
    loading = np.maximum(np.gradient(normal) * fs, 0)
    crackle = (
        p.crackle_n
        * (m.fibre_noise_gain + m.texture_gain)
        * np.sqrt(loading)
        * rng.standard_normal(n)
    )
    touching = normal > 0
    mean_load = float(normal[touching].mean()) if touching.any() else 0.0
    f0, zeta = contact_mode(take.sensor, take.unit, str(take.material), mean_load, p)
    ringing = _resonate(impulses, f0, zeta, fs)
    forces = take.on_pad(
        sign * loads.shear + 0.5 * ringing + crackle, 0.2 * ringing, normal + ringing + crackle
    )
    drive = _unit_vector(rng) * _drive(loads.speed, fs, p)
    return forces * take.unit.coupling * take.sig.patch + drive, np.zeros(n, np.int8)


def _free_space_forces(take: Take) -> tuple[np.ndarray, np.ndarray]:
    """No contact: fingertip inertia, drive vibration and start/stop jerks of the moving arm."""
    n, fs, p, rng = take.n, take.fs, take.p, take.rng
    # motion segments between joint configurations; each starts and stops with a jerk
    seg_s = take.trial_rng.uniform(1.0, 3.0, int(n / fs) + 2)
    bounds = np.cumsum(seg_s) * fs
    bounds = bounds[bounds < n].astype(int)
    phase = np.interp(
        np.arange(n), np.r_[0, bounds, n], np.r_[0, np.arange(1, len(bounds) + 1), len(bounds) + 1]
    )
    speed = take.arm_speed * (1 - np.cos(2 * np.pi * phase))
    accel = np.gradient(speed) * fs / 1000.0  # m/s^2
    rel = take.arm_speed / 25.0
    inertial = (
        p.inertial_n
        * accel[None, :]
        * rng.normal(0, 1, (3, 1))
        / max(np.abs(accel).max(), 1e-9)
        * rel
    )
    impulses = np.zeros(n)
    impulses[bounds] = p.jerk_n * rel * rng.lognormal(0, 0.5, len(bounds))
    ringing = _resonate(impulses, *free_mode(take.unit, p), fs)
    forces = inertial + _unit_vector(rng) * (ringing + _drive(speed, fs, p))
    return forces, np.zeros(n, np.int8)


#: each scenario's contact forces (3, n) and per-sample labels (n,)
SCENARIO_FORCES = {
    "slip": _slip_forces,
    "hold-slip": _hold_slip_forces,
    "press": _press_forces,
    "free-space": _free_space_forces,
}


def _unit_vector(rng: np.random.Generator) -> np.ndarray:
    """A random direction (3, 1): how the fingertip's pose projects a vibration on its axes."""
    v = rng.normal(0, 1, (3, 1))
    return v / np.linalg.norm(v)


def _sense(
    forces: np.ndarray, take: Take, electrode_rng: np.random.Generator | None = None
) -> np.ndarray:
    """What the sensor reports: idle vibration, skin filtering, the finger's roll, mixing,
    high-pass, noise, gain; then, for a sensor with electrodes, their counts from the same
    forces (drawing from ``electrode_rng`` only, so that the other channels are those of a
    sensor without them); (n, recorded channels) float32."""
    n, fs, p, rng, sensor, unit = take.n, take.fs, take.p, take.rng, take.sensor, take.unit
    idle = (
        unit.idle_coupling
        * p.idle_n
        * np.sin(2 * np.pi * p.idle_hz * np.arange(n) / fs + rng.uniform(0, 2 * np.pi))
    )
    forces = forces + idle * np.array([[0.5], [0.5], [1.0]])
    if unit.skin_cutoff_hz is not None:
        forces = _lowpass(forces, unit.skin_cutoff_hz, fs, axis=1)
    out = unit.mixing @ take.sig.roll @ forces  # (channels, n), in the sensor's frame
    if sensor.highpass_hz is not None:
        out = _filtered(_butter(2, sensor.highpass_hz, fs, "highpass"), out, axis=1)
    out = out + rng.normal(0, sensor.noise_floor_n * unit.noise, out.shape)
    channels = (out.T * unit.gain * take.sig.drift * sensor.units_per_newton).astype(np.float32)
    if sensor.electrodes is None:
        return channels
    if electrode_rng is None:
        raise ValueError("a sensor with electrodes needs their random stream")
    return np.hstack([channels, electrode_counts(forces, take, electrode_rng)])


def calibrated_forces(channels: np.ndarray, sensor: Sensor, unit: Unit) -> np.ndarray:
    """The force (3, n) in N that a unit's force channels (n, channels) say, through its
    calibration: the pseudo-inverse of its mix and its gain, as a lab's calibration matrix
    does (in the sensor's frame; the filters, noise and a recording's drift stay in)."""
    forces = np.linalg.pinv(unit.mixing) @ np.asarray(channels, np.float64).T
    return forces / (unit.gain * sensor.units_per_newton)


def electrode_counts(forces: np.ndarray, take: Take, rng: np.random.Generator) -> np.ndarray:
    """What a unit's electrodes read while the contact applies ``forces``.

    Parameters
    ----------
    forces : (3, n) the force at the skin, in N: shear along the finger (the slide), shear
        across it, normal load (see :class:`ElectrodeArray` for the model).
    take : the recording: its sensor type (with electrodes) and unit (:func:`make_unit`), its
        sampling rate (for the electrodes' band) and the physics whose ``signature_spread``
        scales the recording's draws (its own streams are not drawn from).
    rng : the recording's electrode stream: its contact position, resting drift and noise.

    Returns
    -------
    (n, n_electrodes) float32 whole counts in [0, ``full_scale``].
    """
    sensor, unit, fs, p = take.sensor, take.unit, take.fs, take.p
    array, own = sensor.electrodes, unit.electrodes
    if array is None or own is None:
        raise ValueError("electrode_counts needs a sensor type with electrodes and a unit of it")
    k = p.signature_spread
    centre = own.centre_mm + rng.normal(0, array.centre_sd_mm * k, 2)
    drift = rng.normal(0, array.drift_counts * k)
    normal = forces[2]
    # the contact's pressure: a Gaussian of half the Hertz radius, spread by skin and fluid,
    # scaled so that counts_per_n is the change under the centre at 1 N
    hertz_mm = 1e3 * (0.75 * sensor.tip_radius_mm * 1e-3 / unit.tip_modulus_pa) ** (1 / 3)
    width2 = (hertz_mm * np.cbrt(np.maximum(normal, 0.0)) / 2) ** 2 + array.spread_mm**2
    width2_1n = (hertz_mm / 2) ** 2 + array.spread_mm**2
    # squared distance of each electrode from the contact's centre, moved with the skin:
    # |r - s|^2 = |r|^2 - 2 r.s + |s|^2, without an (electrodes, 2, n) array
    rel = np.asarray(array.positions_mm) - centre  # (electrodes, 2)
    shift = array.skin_mm_per_n * forces[:2]  # (2, n)
    dist2 = (rel**2).sum(axis=1)[:, None] - 2 * rel @ shift + (shift**2).sum(axis=0)
    onto_faces = array.normals @ forces  # (electrodes, n): the force pressed onto each face
    load = onto_faces * (width2_1n / width2) * np.exp(-dist2 / (2 * width2))
    pressed = _lowpass(array.counts_per_n * own.gain[:, None] * load, array.band_hz, fs, axis=1)
    counts = own.rest[:, None] + drift - pressed  # a thinner fluid gap: fewer counts
    counts += array.noise_counts * unit.noise * rng.standard_normal(counts.shape, np.float32)
    return np.clip(np.round(counts), 0, array.full_scale).T.astype(np.float32)


def _count(seconds: float, nominal_s: float) -> int:
    """Recordings of about ``nominal_s`` that share ``seconds``: none for none, else at least one."""
    return 0 if seconds <= 0 else max(1, int(round(seconds / nominal_s)))


def _plan(
    design: Design, scale: float
) -> list[tuple[str, str | None, float | None, list[str], float]]:
    """(scenario, material, speed, trial tokens, seconds per recording) for every cell."""
    d = design
    plan = []

    def add(scenario, material, speed, tokens, seconds):
        if tokens and seconds > 0:
            plan.append((scenario, material, speed, tokens, seconds / len(tokens)))

    def regular(n):
        return [str(k) for k in range(n)]

    def long(seconds, nominal):
        return [f"long{k}" for k in range(_count(seconds, nominal))]

    for mat in d.materials:
        for v in d.slip_speeds:
            add("slip", mat, v, regular(d.slip_trials), d.slip_s_per_cell * scale)
    for mat in d.materials:
        add("press", mat, None, regular(d.press_trials), d.press_s_per_material * scale)
    for v in d.free_speeds:
        add("free-space", None, v, regular(d.free_trials), d.free_s_per_speed * scale)
    for mat in d.materials:
        add(
            "press",
            mat,
            None,
            long(d.long_press_s_per_material * scale, d.long_recording_s),
            d.long_press_s_per_material * scale,
        )
    for v in d.free_speeds:
        add(
            "free-space",
            None,
            v,
            long(d.long_free_s_per_speed * scale, d.long_recording_s),
            d.long_free_s_per_speed * scale,
        )
    for mat in d.materials:
        for v in d.slip_speeds:
            seconds = d.onset_s_per_cell * scale
            add("hold-slip", mat, v, regular(_count(seconds, d.onset_recording_s)), seconds)
    return plan


def generate(
    scale: float = 0.05, seed: int = 0, design: Design = Design()
) -> tuple[pd.DataFrame, dict, dict]:
    """Simulate the design of experiments.

    Parameters
    ----------
    scale : fraction of the paper's amount of data (1.0: ~8 M samples per unit for its design).
    seed : every random draw derives from it; each recording has its own keyed streams.
    design : what to simulate (:class:`Design`, its ``physics`` a :class:`Physics`).

    Returns
    -------
    recordings : metadata DataFrame in the dataset format, with a ``trial`` column (recordings
        of the units of one sensor type made at the same time share a trial id) and
        ``univariate_channels`` (``("pac",)`` for the BioTac SP, empty for the others).
    samples : recording_id -> float32 (n_samples, n_channels).
    labels : recording_id -> int8 (n_samples,): 1 while the contact slides, 0 otherwise,
        ``UNLABELLED`` (-1) after the contact is lost in a ``hold-slip`` trial.
    """
    p = design.physics
    rows, samples, labels = [], {}, {}
    units: dict[tuple[str, str], Unit] = {}
    for key, inst, n, row in _recordings(design, scale, seed):
        sensor_type = row[SENSOR_TYPE]
        sensor = SENSORS[sensor_type]
        if (sensor_type, inst) not in units:
            units[sensor_type, inst] = make_unit(seed, sensor_type, inst, p)
        unit = units[sensor_type, inst]
        rng = rng_for(seed, "rec", sensor_type, inst, *key[1:])
        sig = _signature(
            rng_for(seed, "signature", sensor_type, inst, *key[1:]),
            rng_for(seed, "surface", *key),
            p,
        )
        trial_rng = rng_for(seed, "trial", *key)
        take = Take(n, sensor.rate_hz, key[2], key[3], sensor, unit, sig, trial_rng, rng, p)
        forces, label = SCENARIO_FORCES[key[1]](take)
        electrode_rng = rng_for(seed, "electrodes", sensor_type, inst, *key[1:])
        samples[row["recording_id"]] = _sense(forces, take, electrode_rng)
        labels[row["recording_id"]] = label
        rows.append(row)
    return pd.DataFrame(rows), samples, labels


def _recordings(design: Design, scale: float, seed: int):
    """Per recording of the design, in the order :func:`generate` simulates them: its draw key
    (sensor type, scenario, material, speed, trial token), unit instance, number of samples
    and recordings row."""
    if not scale > 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    for sensor_type in design.sensors:
        sensor = SENSORS[sensor_type]
        fs = sensor.rate_hz
        for scenario, material, speed, tokens, seconds in _plan(design, scale):
            n = max(64, int(round(seconds * fs)))
            speed_name = "none" if speed is None else f"{speed:g}"
            for token in tokens:
                key = (sensor_type, scenario, material, speed, token)
                trial_id = "/".join((sensor_type, scenario, material or "none", speed_name, token))
                for inst in sensor.instances:
                    rid = "-".join(
                        (sensor_type, inst, scenario, material or "none", speed_name, token)
                    )
                    yield (
                        key,
                        inst,
                        n,
                        dict(
                            recording_id=rid,
                            sensor_type=sensor_type,
                            sensor_instance=inst,
                            scenario=scenario,
                            material=material,
                            speed_mm_s=speed,
                            sampling_rate_hz=fs,
                            channels=sensor.recorded_channels,
                            units=(sensor.unit,) * len(sensor.recorded_channels),
                            univariate_channels=sensor.univariate_channels,
                            source=f"slipbench.synth v{MODEL_VERSION} seed={seed} scale={scale:g}",
                            trial=trial_id,
                        ),
                    )


def layout(scale: float = 0.05, seed: int = 0, design: Design = Design()) -> pd.DataFrame:
    """The recordings table :func:`generate` would make, with each recording's ``n_samples``,
    without simulating a sample: what planning a run at any scale needs (milliseconds, where
    simulating the paper's size takes many minutes)."""
    rows = [dict(row, n_samples=n) for _, _, n, row in _recordings(design, scale, seed)]
    return pd.DataFrame(rows)


def synthesize(
    out: str | Path, scale: float = 0.05, seed: int = 0, design: Design = Design()
) -> Path:
    """Generate the simulated dataset into folder ``out`` (written atomically)."""
    recordings, samples, labels = generate(scale, seed, design)
    return write_dataset(out, recordings, samples, labels)


def with_physics(design: Design = Design(), **changes) -> Design:
    """A design whose physics differs in the named fields (for ablations and tests)."""
    return replace(design, physics=replace(design.physics, **changes))
