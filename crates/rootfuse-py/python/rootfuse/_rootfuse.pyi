"""Type stubs of the extension module ``rootfuse._rootfuse`` (re-exported by ``rootfuse``).

Units: gyroscope rad/s, accelerometer m/s², magnetometer µT, time s,
quaternions ``[w, x, y, z]`` sensor to earth (ENU), covariances rad², errors degrees.

Checked against the built extension by ``python -m mypy.stubtest rootfuse``
(``tests/test_typing.py``): names, parameters and defaults agree with the runtime. Names with a
leading underscore exist only here (result types).
"""

from os import PathLike
from typing import Any, Dict, List, Literal, Optional, Sequence, Union, final, overload

import numpy as np
import numpy.typing as npt
from typing_extensions import NotRequired, TypedDict

__all__ = [
    "EstimateStream",
    "Filter",
    "Rls",
    "__version__",
    "build_info",
    "consistency",
    "error_series",
    "estimate_arrow",
    "filters",
    "fit_ellipsoid_calibration",
    "heading_offset",
    "lstsq",
    "read_csv",
    "read_estimates",
    "rls_forms",
    "rmse",
    "run_many",
    "scenario_names",
    "simulate",
    "smooth",
    "stress",
    "stress_scenarios",
    "write_estimates",
    "write_recording",
]

# The package version (the crate's, from Cargo.toml).
__version__: str

_FloatArray = npt.NDArray[np.floating[Any]]
_F64 = npt.NDArray[np.float64]
# A series in the dtype asked for (float64 by default, float32 with ``dtype="float32"``).
_SeriesArray = Union[npt.NDArray[np.float64], npt.NDArray[np.float32]]
_U8 = npt.NDArray[np.uint8]
_Bools = npt.NDArray[np.bool_]
_Path = Union[str, "PathLike[str]"]
# A recording as `simulate` and `read_csv` return it (t, gyr, acc, mag, truth, use, name).
_RecordingDict = Dict[str, Any]
# `truth`: an (N, 4) array or a recording dict (its `truth` and `use` are taken).
_Truth = Union[_FloatArray, Dict[str, Any]]
_Use = Union[_Bools, npt.NDArray[np.integer[Any]], _FloatArray, Sequence[Union[bool, int, float]], None]

class _Rejections(TypedDict):
    """Skipped samples (dt, gyr) and corrections (acc, mag, gated), counts."""

    dt: int
    gyr: int
    acc: int
    mag: int
    gated: int
    mag_disturbed: int

class _Series(TypedDict):
    """What ``Filter.update_batch`` returns."""

    quat: _F64
    bias: _F64
    covariance: NotRequired[_F64]
    flags: _U8

class _ManySeries(TypedDict):
    """``run_many`` of (C, N, 3) arrays with ``series=True``: (C, N, ...) arrays."""

    quat: _SeriesArray
    bias: NotRequired[_SeriesArray]
    covariance: NotRequired[_SeriesArray]
    flags: NotRequired[_U8]
    rejections: List[_Rejections]

class _ChannelSeries(TypedDict):
    """One channel of ``run_many`` of lists with ``series=True``: (N_i, ...) arrays."""

    quat: _SeriesArray
    bias: NotRequired[_SeriesArray]
    covariance: NotRequired[_SeriesArray]
    flags: NotRequired[_U8]
    rejections: _Rejections

class _ManyFinal(TypedDict):
    """``run_many`` with ``series=False``: the final state of each channel."""

    quat: _F64
    bias: _F64
    gyro_scale: _F64
    rejections: List[_Rejections]

class _Smoothed(TypedDict):
    quat: _F64
    forward_only: int
    gyro_scale: NotRequired[_F64]

class _Rmse(TypedDict):
    total: float
    heading: float
    inclination: float
    n_used: int
    heading_offset: float

class _Consistency(TypedDict):
    nees_total: float
    coverage_total: float
    nees_inclination: float
    coverage_inclination: float
    n_used: int
    n_invalid: int

@final
class Filter:
    """A registered orientation filter by name (``filters()`` lists them), f32 or f64.

    ``Filter(name, *, dof=None, precision="f64", **params)``: parameters as keyword arguments,
    validated by the registry (ValueError naming the parameter and its range); ``dof`` 6 or 9
    (``gyro`` has no such choice: a ``dof`` for it is a ValueError). One thread at a time.
    """

    def __new__(cls, name: str, *, dof: Optional[int] = None, precision: str = "f64", **params: float) -> Filter: ...
    @property
    def name(self) -> str:
        """Registered name (``"flagship"`` gives ``"sqrt-eskf"``)."""
    @property
    def precision(self) -> str:
        """``"f32"`` or ``"f64"``."""
    @property
    def dof(self) -> Optional[int]:
        """6 or 9; None for ``gyro``."""
    @property
    def params(self) -> Dict[str, float]:
        """Every parameter's value (units in ``filters()``); whole-number kinds as ints, so
        that ``Filter(name, **f.params)`` rebuilds the filter."""
    def update_batch(
        self,
        gyr: _FloatArray,
        acc: _FloatArray,
        mag: Optional[_FloatArray] = None,
        dt: Union[float, _FloatArray, None] = None,
        *,
        t: Optional[_FloatArray] = None,
        covariance: bool = True,
    ) -> _Series:
        """Whole arrays (N, 3) from the current state, GIL released; exactly one of ``dt``
        (s, scalar or (N,)) and ``t`` (s, (N,)). Returns ``quat`` (N, 4), ``bias`` (N, 3)
        rad/s, ``covariance`` (N, 3, 3) rad² (filters that have one, unless
        ``covariance=False``), ``flags`` (N,) uint8. A call with ``t`` after a call with ``t``
        continues its times (a stream fed in chunks); a ``UserWarning`` where most steps
        would be skipped (sample times given as ``dt``, times in ms), and where the stream's
        first samples (until its unit check decides) look like deg/s, g or nT, once per
        sensor until ``reset()``."""
    def update(
        self,
        gyr: Union[Sequence[float], _FloatArray],
        acc: Union[Sequence[float], _FloatArray],
        mag: Union[Sequence[float], _FloatArray, None] = None,
        *,
        dt: float,
    ) -> int:
        """One sample (rad/s, m/s², µT; dt s); returns its flags. The stream's unit check
        reads it too, as in ``update_batch``."""
    @property
    def quat(self) -> _F64:
        """Orientation [w, x, y, z], (4,)."""
    @property
    def bias(self) -> _F64:
        """Gyro-bias estimate, rad/s, (3,)."""
    @property
    def gyro_scale(self) -> _F64:
        """Gyroscope scale-error estimate per sensor axis, a fraction (readings = (1 + s)·rate), (3,); zeros without one."""
    @property
    def covariance(self) -> Optional[_F64]:
        """Attitude-error covariance, rad², earth frame ENU, (3, 3); None without one."""
    @property
    def rejections(self) -> _Rejections:
        """Counts of what was skipped since construction or reset."""
    def set_quat(self, q: Union[Sequence[float], _FloatArray], sigma: Optional[float] = None) -> None:
        """Sets the orientation [w, x, y, z] (normalised) and marks the filter initialised; sigma (rad) sets its covariance too (sqrt-eskf, ekf)."""
    def set_bias(self, bias: Union[Sequence[float], _FloatArray], sigma: Optional[float] = None) -> bool:
        """Sets the gyro bias, rad/s (|component| <= 1); False for filters that cannot hold a 3-axis bias; sigma (rad/s) sets its covariance too."""
    def set_heading(self, heading: float) -> None:
        """Turns about earth-up to this heading, rad (counter-clockwise from north)."""
    def forget_field_reference(self) -> None:
        """The magnetometer readings change from the next sample on because a new calibration is applied: the next usable reading becomes the field reference, pointing north (sqrt-eskf 9D; nothing for the other filters)."""
    def reset(self) -> None:
        """Back to the freshly built state (same parameters and precision); a new stream
        for the unit check."""

def filters() -> List[Dict[str, Any]]:
    """Every registered filter: name, description, params (name, kind, default, unit, min,
    max, doc)."""

def smooth(
    name: str,
    gyr: _FloatArray,
    acc: _FloatArray,
    mag: Optional[_FloatArray] = None,
    *,
    t: Optional[_FloatArray] = None,
    dt: Optional[float] = None,
    dof: Optional[int] = None,
    **params: float,
) -> _Smoothed:
    """Offline forward-backward smoothing (f64) for filters with an attitude covariance:
    ``{"quat": (N, 4), "forward_only": int}``, and for the flagship ``"gyro_scale"`` (3,),
    unless ``smoothing_gyro_scale=0``. Arrays in other units than s, rad/s, m/s², µT (a
    gyroscope in deg/s) raise a ``UserWarning`` naming the sensor."""

@overload
def run_many(
    name: str,
    gyr: _FloatArray,
    acc: _FloatArray,
    mag: Optional[_FloatArray] = None,
    dt: Union[float, _FloatArray, None] = None,
    *,
    t: Optional[_FloatArray] = None,
    dof: Optional[int] = None,
    precision: str = "f32",
    channel_params: Optional[List[Dict[str, float]]] = None,
    series: Literal[True] = True,
    bias: bool = True,
    covariance: bool = False,
    flags: bool = True,
    dtype: Union[str, type, None] = None,
    out: Optional[Dict[str, npt.NDArray[Any]]] = None,
    **params: float,
) -> _ManySeries:
    """(C, N, 3) arrays through the SIMD batch engine on all cores (f32 by default); each
    channel equals a ``Filter`` run bit for bit. ``dtype="float32"``: float32 series (half
    the memory; the same values with ``precision="f32"``). ``out``: a dict of arrays of the
    result's keys and shapes to write into (reused from call to call), returned. The first,
    the last and two channels between are checked for their units and steps before any
    filter runs (a ``UserWarning`` naming the channel)."""

@overload
def run_many(
    name: str,
    gyr: Sequence[_FloatArray],
    acc: Sequence[_FloatArray],
    mag: Optional[Sequence[_FloatArray]] = None,
    dt: Union[float, Sequence[_FloatArray], None] = None,
    *,
    t: Optional[Sequence[_FloatArray]] = None,
    dof: Optional[int] = None,
    precision: str = "f32",
    channel_params: Optional[List[Dict[str, float]]] = None,
    series: Literal[True] = True,
    bias: bool = True,
    covariance: bool = False,
    flags: bool = True,
    dtype: Union[str, type, None] = None,
    **params: float,
) -> List[_ChannelSeries]:
    """Lists of (N_i, 3) arrays (channels of different lengths): one dict per channel."""

@overload
def run_many(
    name: str,
    gyr: Union[_FloatArray, Sequence[_FloatArray]],
    acc: Union[_FloatArray, Sequence[_FloatArray]],
    mag: Union[_FloatArray, Sequence[_FloatArray], None] = None,
    dt: Union[float, _FloatArray, Sequence[_FloatArray], None] = None,
    *,
    t: Union[_FloatArray, Sequence[_FloatArray], None] = None,
    dof: Optional[int] = None,
    precision: str = "f32",
    channel_params: Optional[List[Dict[str, float]]] = None,
    series: Literal[False],
    bias: bool = True,
    covariance: bool = False,
    flags: bool = True,
    dtype: Union[str, type, None] = None,
    **params: float,
) -> _ManyFinal:
    """``series=False``: the final state of each channel, (C, ...) arrays."""

@overload
def run_many(
    name: str,
    gyr: Union[_FloatArray, Sequence[_FloatArray]],
    acc: Union[_FloatArray, Sequence[_FloatArray]],
    mag: Union[_FloatArray, Sequence[_FloatArray], None] = None,
    dt: Union[float, _FloatArray, Sequence[_FloatArray], None] = None,
    *,
    t: Union[_FloatArray, Sequence[_FloatArray], None] = None,
    dof: Optional[int] = None,
    precision: str = "f32",
    channel_params: Optional[List[Dict[str, float]]] = None,
    series: bool,
    bias: bool = True,
    covariance: bool = False,
    flags: bool = True,
    dtype: Union[str, type, None] = None,
    out: Optional[Dict[str, npt.NDArray[Any]]] = None,
    **params: float,
) -> Union[_ManySeries, List[_ChannelSeries], _ManyFinal]:
    """``series`` known only when the program runs: any of the results above."""

def estimate_arrow(
    source: Any,
    filter: str,
    *,
    precision: str = "f64",
    dof: Optional[int] = None,
    bias: bool = False,
    covariance: bool = False,
    flags: bool = False,
    device_params: Optional[Dict[Any, Dict[str, float]]] = None,
    **params: float,
) -> EstimateStream:
    """Estimates of the IMU rows of an Arrow stream (anything with ``__arrow_c_stream__``) or
    of a Parquet or Arrow IPC file (a ``str`` or ``os.PathLike`` path, read in Rust),
    computed as they are read."""

@final
class EstimateStream:
    """Estimates of a fleet as an Arrow stream (the Arrow PyCapsule interface), read once."""

    def __arrow_c_stream__(self, requested_schema: Optional[object] = None) -> object:
        """Hands the stream over (once), as a PyCapsule."""
    @property
    def column_names(self) -> List[str]:
        """``device`` (when the input has one), ``t``, ``qw..qz``, then the columns asked for."""
    def summary(self) -> Optional[Dict[str, Any]]:
        """After the whole stream was read: rows, devices, devices_with_defaults,
        unseen_devices, rejections; None before."""

@final
class Rls:
    """Recursive least squares in one of six forms (``rls_forms()``), n = 1..8, f32/f64."""

    def __new__(
        cls,
        form: str,
        n: int,
        *,
        x0: Optional[_FloatArray] = None,
        p0: Union[float, _FloatArray, None] = None,
        lam: float = 1.0,
        p_min: Optional[float] = None,
        p_max: Optional[float] = None,
        compensated: bool = True,
        precision: str = "f64",
    ) -> Rls: ...
    @property
    def form(self) -> str: ...
    @property
    def n(self) -> int: ...
    @property
    def precision(self) -> str: ...
    def update(self, h: _FloatArray, z: float, weight: float = 1.0) -> bool:
        """One measurement z = hᵀx + v, weight 1/var(v); True if applied."""
    def run(
        self, h: _FloatArray, z: _FloatArray, weights: Union[float, _FloatArray, None] = None
    ) -> Dict[str, npt.NDArray[Any]]:
        """K measurements: ``estimate`` (K, n), ``accepted``, ``min_pivot``, ``max_pivot``,
        ``trace``, ``lost_definiteness`` (K,)."""
    def predict(self, f: _FloatArray, lam: float = 1.0) -> bool:
        """Potter only: x ← F x, P ← F P Fᵀ / lam; ValueError for other forms or with bounds."""
    def time_update(self, q: _FloatArray) -> bool:
        """Bierman U-D only: P ← P + diag(q); ValueError for other forms."""
    @property
    def estimate(self) -> _F64: ...
    @property
    def covariance(self) -> _F64: ...
    @property
    def health(self) -> Dict[str, Any]: ...

def rls_forms() -> List[str]: ...
def fit_ellipsoid_calibration(
    samples: _FloatArray, *, norm: Optional[float] = None, min_coverage: float = 0.4
) -> Dict[str, Any]:
    """y_cal = S·(y_raw − h) from raw (N, 3) readings: ``matrix``, ``offset``, ``norm``,
    ``model`` (what the data determined), ``refused``, quality figures; ValueError on refusal,
    also for a three-dimensional fit to readings covering less than ``min_coverage`` of the
    sphere of directions (it extrapolates the rest)."""

def lstsq(
    h: _FloatArray,
    z: _FloatArray,
    *,
    weights: Optional[_FloatArray] = None,
    covariance: Optional[_FloatArray] = None,
    method: str = "qr",
    rank_tolerance: Optional[float] = None,
    equilibrate: bool = True,
    refinement_steps: int = 3,
    precision: str = "f64",
) -> Dict[str, Any]:
    """Weighted least squares by QR, pivoted QR, SVD or normal equations (breakdown raised as
    ValueError)."""

def stress(scenario: Optional[str] = None, *, scale: float = 1.0, long: bool = False) -> List[Dict[str, Any]]:
    """The RLS stress scenarios against a double-double reference, one row per form,
    precision and parameter. ``scale`` multiplies every step count (at most 100)."""

def stress_scenarios() -> List[str]: ...
def rmse(est: _FloatArray, truth: _Truth, *, use: _Use = None, dof: int = 9) -> _Rmse:
    """BROAD RMSE in degrees (total, heading, inclination), 6D heading offset removed for
    dof=6."""

def error_series(est: _FloatArray, truth: _Truth, *, use: _Use = None, dof: int = 9) -> Dict[str, Any]:
    """Per-sample BROAD errors, degrees."""

def heading_offset(est: _FloatArray, truth: _Truth, *, use: _Use = None) -> Optional[float]:
    """The 6D heading offset, degrees."""

def consistency(
    est: _FloatArray,
    cov: _FloatArray,
    truth: _Truth,
    *,
    use: _Use = None,
    dof: int = 9,
    floor_deg: float = 0.0,
    skip: float = 0.1,
) -> _Consistency:
    """NEES/k and 95 % coverage of a reported attitude covariance, total and inclination."""

def simulate(scenario: str, *, seed: int = 0, duration_s: float = 10.0, rate_hz: float = 100.0) -> _RecordingDict:
    """A simulated recording (t, gyr, acc, mag, truth, use, name)."""

def scenario_names() -> List[str]: ...
def read_csv(path: _Path, *, units: Optional[str] = None, strict: bool = False) -> _RecordingDict:
    """A recording CSV as a dict (t, gyr, acc, mag, truth, use, name), converted from `units`
    ("time=ms,gyro=deg/s,acc=g,mag=nT"); readings that look like another unit warn."""

def write_recording(
    path: _Path,
    t: _FloatArray,
    gyr: _FloatArray,
    acc: _FloatArray,
    mag: Optional[_FloatArray] = None,
    *,
    truth: Optional[_FloatArray] = None,
    use: _Use = None,
) -> None:
    """A recording as CSV; what ``read_csv`` would refuse is a ValueError (row, column)."""

def write_estimates(
    path: _Path, t: _FloatArray, quat: _FloatArray, extra: Optional[Dict[str, _FloatArray]] = None
) -> None:
    """Estimates as CSV; what ``read_estimates`` would refuse is a ValueError (row, column)."""

def read_estimates(path: _Path) -> Dict[str, _F64]:
    """``t``, ``quat`` and every other column (``bx``, ``p_xx``, ``flags``, ...) by name."""

def build_info() -> Dict[str, List[str]]:
    """CPU extensions compiled in, and those this CPU lacks."""
