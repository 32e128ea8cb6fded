"""Type stubs of rootfuse (the extension module ``rootfuse._rootfuse``).

Units: gyroscope rad/s, accelerometer m/s², magnetometer any consistent unit, time s,
quaternions ``[w, x, y, z]`` sensor to earth (ENU), covariances rad², errors degrees.
"""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

# The package version (the crate's, from Cargo.toml).
__version__: str

FloatArray = npt.NDArray[np.floating[Any]]
F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]
Bools = npt.NDArray[np.bool_]
Path = Union[str, "PathLike[str]"]

FLAG_DT: int
FLAG_GYR: int
FLAG_ACC: int
FLAG_MAG: int
FLAG_GATED: int
FLAG_REST: int
FLAG_MAG_DISTURBED: int

class Rejections(TypedDict):
    """Skipped samples (dt, gyr) and corrections (acc, mag, gated), counts."""
    dt: int
    gyr: int
    acc: int
    mag: int
    gated: int
    mag_disturbed: int

class Filter:
    """A registered orientation filter by name (``filters()`` lists them), f32 or f64.

    ``Filter(name, dof=None, precision="f64", **params)``: parameters as keyword arguments,
    validated by the registry (ValueError naming the parameter and its range); ``dof`` 6 or 9
    (``gyro`` has no such choice: a ``dof`` for it is a ValueError).
    """
    def __init__(self, name: str, *, dof: Optional[int] = None, precision: str = "f64", **params: float) -> None: ...
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
        """Every parameter's value (units in ``filters()``)."""
    def update_batch(
        self,
        gyr: FloatArray,
        acc: FloatArray,
        mag: Optional[FloatArray] = None,
        dt: Union[float, FloatArray, None] = None,
        *,
        t: Optional[FloatArray] = None,
    ) -> Dict[str, npt.NDArray[Any]]:
        """Whole arrays (N, 3) from the current state, GIL released; exactly one of ``dt``
        (s, scalar or (N,)) and ``t`` (s, (N,)). Returns ``quat`` (N, 4), ``bias`` (N, 3)
        rad/s, ``covariance`` (N, 3, 3) rad² (filters that have one), ``flags`` (N,) uint8."""
    def update(
        self,
        gyr: Union[Sequence[float], FloatArray],
        acc: Union[Sequence[float], FloatArray],
        mag: Union[Sequence[float], FloatArray, None] = None,
        *,
        dt: float,
    ) -> int:
        """One sample (rad/s, m/s², any unit; dt s); returns its flags."""
    @property
    def quat(self) -> F64:
        """Orientation [w, x, y, z], (4,)."""
    @property
    def bias(self) -> F64:
        """Gyro-bias estimate, rad/s, (3,)."""
    @property
    def covariance(self) -> Optional[F64]:
        """Attitude-error covariance, rad², earth frame ENU, (3, 3); None without one."""
    @property
    def rejections(self) -> Rejections:
        """Counts of what was skipped since construction or reset."""
    def set_quat(self, q: Union[Sequence[float], FloatArray]) -> None:
        """Sets the orientation [w, x, y, z] (normalised) and marks the filter initialised."""
    def set_bias(self, bias: Union[Sequence[float], FloatArray]) -> bool:
        """Sets the gyro bias, rad/s; False for filters without one."""
    def set_heading(self, heading: float) -> None:
        """Turns about earth-up to this heading, rad (counter-clockwise from north)."""
    def reset(self) -> None:
        """Back to the freshly built state (same parameters and precision)."""

def filters() -> List[Dict[str, Any]]:
    """Every registered filter: name, description, params (name, kind, default, unit, min,
    max, doc)."""

def smooth(
    name: str,
    gyr: FloatArray,
    acc: FloatArray,
    mag: Optional[FloatArray] = None,
    *,
    t: Optional[FloatArray] = None,
    dt: Optional[float] = None,
    dof: Optional[int] = None,
    **params: float,
) -> Dict[str, Any]:
    """Offline forward-backward smoothing (f64) for filters with an attitude covariance:
    ``{"quat": (N, 4), "forward_only": int}``."""

def run_many(
    name: str,
    gyr: Union[FloatArray, Sequence[FloatArray]],
    acc: Union[FloatArray, Sequence[FloatArray]],
    mag: Union[FloatArray, Sequence[FloatArray], None] = None,
    dt: Union[float, FloatArray, Sequence[FloatArray], None] = None,
    *,
    t: Union[FloatArray, Sequence[FloatArray], None] = None,
    dof: Optional[int] = None,
    precision: str = "f32",
    channel_params: Optional[List[Dict[str, float]]] = None,
    series: bool = True,
    bias: bool = True,
    covariance: bool = False,
    flags: bool = True,
    **params: float,
) -> Union[Dict[str, Any], List[Dict[str, Any]]]:
    """Many channels ((C, N, 3) arrays or lists of (N_i, 3)) through the SIMD batch engine on
    all cores; each channel equals a ``Filter`` run bit for bit."""

class Rls:
    """Recursive least squares in one of six forms (``rls_forms()``), n = 1..8, f32/f64."""
    def __init__(
        self,
        form: str,
        n: int,
        *,
        x0: Optional[FloatArray] = None,
        p0: Union[float, FloatArray, None] = None,
        lam: float = 1.0,
        p_min: Optional[float] = None,
        p_max: Optional[float] = None,
        compensated: bool = True,
        precision: str = "f64",
    ) -> None: ...
    @property
    def form(self) -> str: ...
    @property
    def n(self) -> int: ...
    @property
    def precision(self) -> str: ...
    def update(self, h: FloatArray, z: float, weight: float = 1.0) -> bool:
        """One measurement z = hᵀx + v, weight 1/var(v); True if applied."""
    def run(self, h: FloatArray, z: FloatArray, weights: Union[float, FloatArray, None] = None) -> Dict[str, npt.NDArray[Any]]:
        """K measurements: ``estimate`` (K, n), ``accepted``, ``min_pivot``, ``max_pivot``,
        ``trace``, ``lost_definiteness`` (K,)."""
    def predict(self, f: FloatArray, lam: float = 1.0) -> bool:
        """Potter only: x ← F x, P ← F P Fᵀ / lam; ValueError for other forms or with bounds."""
    def time_update(self, q: FloatArray) -> bool:
        """Bierman U-D only: P ← P + diag(q); ValueError for other forms."""
    @property
    def estimate(self) -> F64: ...
    @property
    def covariance(self) -> F64: ...
    @property
    def health(self) -> Dict[str, Any]: ...

def rls_forms() -> List[str]: ...

def fit_ellipsoid_calibration(samples: FloatArray, *, norm: Optional[float] = None) -> Dict[str, Any]:
    """y_cal = S·(y_raw − h) from raw (N, 3) readings: ``matrix``, ``offset``, ``norm``,
    ``model`` (what the data determined), ``refused``, quality figures; ValueError on refusal."""

def lstsq(
    h: FloatArray,
    z: FloatArray,
    *,
    weights: Optional[FloatArray] = None,
    covariance: Optional[FloatArray] = None,
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
    precision and parameter."""

def stress_scenarios() -> List[str]: ...

def rmse(est: FloatArray, truth: Union[FloatArray, Dict[str, Any]], *, use: Optional[npt.ArrayLike] = None, dof: int = 9) -> Dict[str, float]:
    """BROAD RMSE in degrees (total, heading, inclination), 6D heading offset removed for
    dof=6."""

def error_series(est: FloatArray, truth: Union[FloatArray, Dict[str, Any]], *, use: Optional[npt.ArrayLike] = None, dof: int = 9) -> Dict[str, Any]:
    """Per-sample BROAD errors, degrees."""

def heading_offset(est: FloatArray, truth: Union[FloatArray, Dict[str, Any]], *, use: Optional[npt.ArrayLike] = None) -> Optional[float]:
    """The 6D heading offset, degrees."""

def consistency(est: FloatArray, cov: FloatArray, truth: Union[FloatArray, Dict[str, Any]], *, use: Optional[npt.ArrayLike] = None, dof: int = 9, floor_deg: float = 0.0, skip: float = 0.1) -> Dict[str, float]:
    """NEES/k and 95 % coverage of a reported attitude covariance, total and inclination."""

def simulate(scenario: str, *, seed: int = 0, duration_s: float = 10.0, rate_hz: float = 100.0) -> Dict[str, Any]:
    """A simulated recording (t, gyr, acc, mag, truth, use, name)."""

def scenario_names() -> List[str]: ...

def read_csv(path: Path, *, units: Optional[str] = None, strict: bool = False) -> Dict[str, Any]:
    """A recording CSV as a dict (t, gyr, acc, mag, truth, use, name), converted from `units`
    ("time=ms,gyro=deg/s,acc=g,mag=nT"); readings that look like another unit warn."""

def write_recording(
    path: Path,
    t: FloatArray,
    gyr: FloatArray,
    acc: FloatArray,
    mag: Optional[FloatArray] = None,
    *,
    truth: Optional[FloatArray] = None,
    use: Optional[npt.ArrayLike] = None,
) -> None: ...

def write_estimates(path: Path, t: FloatArray, quat: FloatArray, extra: Optional[Dict[str, FloatArray]] = None) -> None: ...

def read_estimates(path: Path) -> Dict[str, F64]: ...

def build_info() -> Dict[str, List[str]]:
    """CPU extensions compiled in, and those this CPU lacks."""
