"""Capture profiles: camera, lens, DOE, simulation and calibration plan, read from TOML and validated.

Every field is checked for type and range; unknown keys are errors (a typo must not fall back to a
default silently). Errors name the file, the section and the key. Lengths are in metres.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

from hdrcam.errors import ProfileError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

PROFILE_DIRECTORY = Path(__file__).resolve().parent.parent / "capture_profiles"
DEFAULT_PROFILE = "sony-a7-zeiss50-rank1"
CFA_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
DOE_KINDS = ("rank1", "freeform", "none")
PROPAGATION_MODELS = ("fresnel", "angular_spectrum", "fraunhofer")
# Plausible ranges: a value outside them is a unit or typing mistake (metres, not millimetres), not a camera.
WAVELENGTH_RANGE_M = (200e-9, 2000e-9)
PIXEL_PITCH_RANGE_M = (0.3e-6, 100e-6)
FOCAL_LENGTH_RANGE_M = (1e-3, 10.0)
MAX_SENSOR_SIDE_PX = 100_000
MAX_LEVELS = 2 ** 16


@dataclasses.dataclass(frozen=True)
class CameraSpec:
    model: str
    pixel_pitch_m: float
    width_px: int
    height_px: int
    bit_depth: int
    black_level_dn: int
    white_level_dn: int
    cfa_pattern: str
    full_well_e: float
    read_noise_e: float


@dataclasses.dataclass(frozen=True)
class LensSpec:
    model: str
    focal_length_m: float
    f_number: float


@dataclasses.dataclass(frozen=True)
class DoeSpec:
    kind: str  # rank1 | freeform | none
    aperture_m: float
    material: str
    feature_size_m: float
    levels: int
    h_max_m: float  # one full wave of phase at design_wavelength_m
    design_wavelength_m: float
    rank: int
    substrate_thickness_m: float


@dataclasses.dataclass(frozen=True)
class SimulationSpec:
    """Wave-optics settings. Bands are (shortest, longest) wavelength in metres, ordered R, G, B."""

    band_edges_m: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]
    wavelengths_per_band: int
    psf_size_px: int
    propagation: str
    energy_target: float
    energy_centre_radius_px: int


@dataclasses.dataclass(frozen=True)
class CalibrationSpec:
    point_source_distance_m: float
    focus_distance_m: float
    stops: int
    ev_step: float
    target_snr: float = 20.0  # --auto: the longest frame's SNR at snr_percentile of the region of interest
    snr_percentile: float = 5.0


@dataclasses.dataclass(frozen=True)
class Profile:
    name: str
    path: Path
    camera: CameraSpec
    lens: LensSpec
    doe: DoeSpec
    simulation: SimulationSpec
    calibration: CalibrationSpec

    @property
    def sensor_distance_m(self) -> float:
        """Lens-to-sensor distance that focuses the focus distance (thin-lens equation)."""
        return image_distance_m(self.lens.focal_length_m, self.calibration.focus_distance_m)


def image_distance_m(focal_length_m: float, object_distance_m: float) -> float:
    """Thin-lens image distance 1 / (1/f - 1/z); f for an object at infinity."""
    if object_distance_m == float("inf"):
        return focal_length_m
    if object_distance_m <= focal_length_m:
        raise ProfileError(f"an object at {object_distance_m} m is inside the focal length {focal_length_m} m")
    return 1.0 / (1.0 / focal_length_m - 1.0 / object_distance_m)


class _Section:
    """Takes validated values out of one TOML table; reports leftovers as unknown keys."""

    def __init__(self, source: Path, name: str, table: Any):
        if not isinstance(table, dict):
            raise ProfileError(f"{source}: [{name}] is missing or not a table")
        self.source, self.name, self.table = source, name, dict(table)

    def fail(self, key: str, message: str) -> ProfileError:
        return ProfileError(f"{self.source}: [{self.name}] {key}: {message}")

    def number(self, key: str, *, positive: bool = True, integer: bool = False, default: Any = None,
               minimum: float | None = None, maximum: float | None = None, infinite: bool = False):
        """A number (``integer``: an int); finite unless ``infinite`` (a distance may be inf), positive
        unless told otherwise, within [minimum, maximum] where given."""
        value = self.table.pop(key, default)
        if value is None:
            raise self.fail(key, "is required")
        kinds = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, kinds):
            raise self.fail(key, f"expected {'an integer' if integer else 'a number'}, got {value!r}")
        if math.isnan(value) or (math.isinf(value) and not (infinite and value > 0)):
            raise self.fail(key, f"must be a finite number, got {value!r}")
        if positive and not value > 0:
            raise self.fail(key, f"must be positive, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.fail(key, f"must be at least {minimum:g}, got {value!r}")
        if maximum is not None and value > maximum:
            raise self.fail(key, f"must be at most {maximum:g}, got {value!r}")
        return value if integer else float(value)

    def text(self, key: str, *, choices: tuple[str, ...] | None = None, default: str | None = None) -> str:
        value = self.table.pop(key, default)
        if not isinstance(value, str):
            raise self.fail(key, f"expected a string, got {value!r}")
        if choices and value not in choices:
            raise self.fail(key, f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def band(self, key: str) -> tuple[float, float]:
        value = self.table.pop(key, None)
        if (not isinstance(value, list) or len(value) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and WAVELENGTH_RANGE_M[0] <= v <= WAVELENGTH_RANGE_M[1] for v in value)
                or not value[0] <= value[1]):
            raise self.fail(key, f"expected [shortest, longest] wavelengths in metres within "
                                 f"{WAVELENGTH_RANGE_M[0]:g} .. {WAVELENGTH_RANGE_M[1]:g}, got {value!r}")
        return float(value[0]), float(value[1])

    def finish(self) -> None:
        if self.table:
            raise self.fail(", ".join(sorted(self.table)), "unknown key")


def _check_simulation(path: Path, camera: CameraSpec, lens: LensSpec, doe: DoeSpec,
                      simulation: SimulationSpec) -> None:
    """Values that are each in range but do not fit together."""
    from hdrcam.optics.grid import max_unaliased_pitch_m

    def fail(section: str, key: str, message: str) -> ProfileError:
        return ProfileError(f"{path}: [{section}] {key}: {message}")

    centres = [sum(band) / 2 for band in simulation.band_edges_m]
    if not centres[0] > centres[1] > centres[2]:
        raise fail("simulation", "red_band_m, green_band_m, blue_band_m", "bands must go from long (red) to short "
                   f"(blue) wavelengths, got centres {', '.join(f'{c * 1e9:g} nm' for c in centres)}")
    if simulation.psf_size_px % 2 == 0:
        raise fail("simulation", "psf_size_px", f"must be odd (the optical axis is the centre pixel), got "
                   f"{simulation.psf_size_px}")
    if 2 * simulation.energy_centre_radius_px + 1 > simulation.psf_size_px:
        raise fail("simulation", "energy_centre_radius_px", f"a centre of {2 * simulation.energy_centre_radius_px + 1}"
                   f" px does not fit in the {simulation.psf_size_px} px PSF")
    shortest_m = min(band[0] for band in simulation.band_edges_m)
    limit_m = max_unaliased_pitch_m(doe.aperture_m, lens.focal_length_m, shortest_m)
    pitch_m = camera.pixel_pitch_m / max(1, math.ceil(camera.pixel_pitch_m / limit_m - 1e-9))
    grid_sampled = simulation.propagation != "fraunhofer"  # the chirp-z model samples the features themselves
    if grid_sampled and doe.kind != "none" and doe.feature_size_m < pitch_m:
        raise fail("doe", "feature_size_m", f"{doe.feature_size_m:g} m is below the simulation pitch {pitch_m:.4g} m "
                   "(pixel pitch / the samples per pixel the aperture needs); no simulation could resolve it")
    if doe.feature_size_m > doe.aperture_m:
        raise fail("doe", "feature_size_m", f"{doe.feature_size_m:g} m is larger than the DOE aperture "
                   f"{doe.aperture_m:g} m")
    features = math.ceil(doe.aperture_m / doe.feature_size_m - 1e-9)
    if doe.rank > features:
        raise fail("doe", "rank", f"{doe.rank} is more than the {features} features across the DOE")


def resolve_profile_path(name_or_path: str | Path) -> Path:
    """A path to a .toml file, or a profile name looked up in ./capture_profiles and the repository's."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.is_file():
        if not candidate.is_file():
            raise ProfileError(f"{candidate}: no such profile file")
        return candidate
    for folder in (Path.cwd() / "capture_profiles", PROFILE_DIRECTORY):
        path = folder / f"{name_or_path}.toml"
        if path.is_file():
            return path
    known = sorted(p.stem for p in PROFILE_DIRECTORY.glob("*.toml"))
    raise ProfileError(f"unknown profile {name_or_path!r}; give a .toml path or one of: {', '.join(known)}")


def _full_wave(path: Path, doe_table, material: str) -> dict:
    """h_max_m and design_wavelength_m from whichever one [doe] gives (the other follows from the dispersion)."""
    from hdrcam.optics.fabrication import design_wavelength_m
    from hdrcam.optics.materials import full_wave_height_m, refractive_index

    given = [key for key in ("design_wavelength_m", "h_max_m") if key in doe_table.table]
    if len(given) != 1:
        raise ProfileError(f"{path}: [doe] give exactly one of design_wavelength_m (h_max = one wave there) and "
                           f"h_max_m, got {given or 'neither'}")
    if given[0] == "design_wavelength_m":
        wavelength = doe_table.number("design_wavelength_m", minimum=WAVELENGTH_RANGE_M[0],
                                      maximum=WAVELENGTH_RANGE_M[1])
        return {"h_max_m": full_wave_height_m(material, wavelength), "design_wavelength_m": wavelength}
    h_max = doe_table.number("h_max_m", maximum=100e-6)
    return {"h_max_m": h_max, "design_wavelength_m": design_wavelength_m(h_max, lambda w: refractive_index(material, w))}


def load_profile(name_or_path: str | Path = DEFAULT_PROFILE) -> Profile:
    """Read and validate a capture profile (see capture_profiles/*.toml for the schema by example)."""
    path = resolve_profile_path(name_or_path)
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ProfileError(f"{path}: not valid TOML ({error})") from None
    top = _Section(path, "top level", document)
    name = top.text("name", default=path.stem)
    sections = {key: top.table.pop(key, None) for key in ("camera", "lens", "doe", "simulation", "calibration")}
    top.finish()

    camera_table = _Section(path, "camera", sections["camera"])
    camera = CameraSpec(
        model=camera_table.text("model"),
        pixel_pitch_m=camera_table.number("pixel_pitch_m", minimum=PIXEL_PITCH_RANGE_M[0],
                                          maximum=PIXEL_PITCH_RANGE_M[1]),
        width_px=camera_table.number("width_px", integer=True, minimum=2, maximum=MAX_SENSOR_SIDE_PX),
        height_px=camera_table.number("height_px", integer=True, minimum=2, maximum=MAX_SENSOR_SIDE_PX),
        bit_depth=camera_table.number("bit_depth", integer=True, minimum=8, maximum=16),
        black_level_dn=camera_table.number("black_level_dn", integer=True, positive=False),
        white_level_dn=camera_table.number("white_level_dn", integer=True),
        cfa_pattern=camera_table.text("cfa_pattern", choices=CFA_PATTERNS),
        full_well_e=camera_table.number("full_well_e"),
        read_noise_e=camera_table.number("read_noise_e", positive=False),
    )
    camera_table.finish()
    if not 0 <= camera.black_level_dn < camera.white_level_dn <= 2 ** camera.bit_depth - 1:
        raise ProfileError(f"{path}: [camera] need 0 <= black_level_dn < white_level_dn <= 2^bit_depth - 1, got "
                           f"{camera.black_level_dn}, {camera.white_level_dn}, {camera.bit_depth} bits")

    lens_table = _Section(path, "lens", sections["lens"])
    lens = LensSpec(model=lens_table.text("model"),
                    focal_length_m=lens_table.number("focal_length_m", minimum=FOCAL_LENGTH_RANGE_M[0],
                                                     maximum=FOCAL_LENGTH_RANGE_M[1]),
                    f_number=lens_table.number("f_number", minimum=0.5, maximum=128))
    lens_table.finish()

    doe_table = _Section(path, "doe", sections["doe"])
    kind = doe_table.text("kind", choices=DOE_KINDS)
    material = doe_table.text("material", choices=("fused_silica",))
    doe = DoeSpec(
        kind=kind,
        aperture_m=doe_table.number("aperture_m"),
        material=material,
        feature_size_m=doe_table.number("feature_size_m"),
        levels=doe_table.number("levels", integer=True, maximum=MAX_LEVELS),
        **_full_wave(path, doe_table, material),
        rank=doe_table.number("rank", integer=True, default=3),
        substrate_thickness_m=doe_table.number("substrate_thickness_m"),
    )
    doe_table.finish()
    if doe.levels & (doe.levels - 1) or doe.levels < 2:
        raise ProfileError(f"{path}: [doe] levels: must be a power of two >= 2 (one mask per bit), got {doe.levels}")
    lens_pupil_m = lens.focal_length_m / lens.f_number
    if doe.aperture_m > lens_pupil_m:
        raise ProfileError(f"{path}: [doe] aperture_m: {doe.aperture_m} m is wider than the lens pupil "
                           f"{lens_pupil_m:.4g} m (f / f_number); the DOE must be the aperture stop")

    simulation_table = _Section(path, "simulation", sections["simulation"])
    simulation = SimulationSpec(
        band_edges_m=(simulation_table.band("red_band_m"), simulation_table.band("green_band_m"),
                      simulation_table.band("blue_band_m")),
        wavelengths_per_band=simulation_table.number("wavelengths_per_band", integer=True, default=1),
        psf_size_px=simulation_table.number("psf_size_px", integer=True),
        propagation=simulation_table.text("propagation", choices=PROPAGATION_MODELS, default="fresnel"),
        energy_target=simulation_table.number("energy_target", maximum=1.0, default=0.94),
        energy_centre_radius_px=simulation_table.number("energy_centre_radius_px", integer=True, positive=False,
                                                        default=1),
    )
    simulation_table.finish()
    _check_simulation(path, camera, lens, doe, simulation)

    calibration_table = _Section(path, "calibration", sections["calibration"])
    calibration = CalibrationSpec(
        point_source_distance_m=calibration_table.number("point_source_distance_m", infinite=True),
        focus_distance_m=calibration_table.number("focus_distance_m", infinite=True),
        stops=calibration_table.number("stops", integer=True, maximum=64),
        ev_step=calibration_table.number("ev_step", maximum=10.0),
        target_snr=calibration_table.number("target_snr", default=20.0),
        snr_percentile=calibration_table.number("snr_percentile", default=5.0, maximum=100.0),
    )
    calibration_table.finish()
    if abs(round(calibration.ev_step * 3) - calibration.ev_step * 3) > 0.01:
        raise ProfileError(f"{path}: [calibration] ev_step: must be a multiple of 1/3 EV (the shutter's notches), "
                           f"got {calibration.ev_step}")
    calibration = dataclasses.replace(calibration, ev_step=round(calibration.ev_step * 3) / 3)  # 0.333: 1/3 exactly
    for key in ("point_source_distance_m", "focus_distance_m"):
        if getattr(calibration, key) <= lens.focal_length_m:
            raise ProfileError(f"{path}: [calibration] {key}: {getattr(calibration, key)} m is not beyond the focal "
                               f"length {lens.focal_length_m} m; nothing there is imaged")
    return Profile(name=name, path=path, camera=camera, lens=lens, doe=doe, simulation=simulation,
                   calibration=calibration)
