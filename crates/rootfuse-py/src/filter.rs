//! One filter, one channel: `Filter` (whole arrays with `update_batch`, or one sample at a
//! time).

use crate::arrays::{self, DofArg, Steps, same_length, sensor_matrix};
use crate::inputs::Inputs;
use crate::unit_warnings::{JUDGE_EVERY, Judged, StreamCheck, deliver, warn_if_most_steps_skipped};
use numpy::{PyArray1, PyArrayMethods, ndarray::Array2};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use rootfuse_attitude::filters::{ParamKind, Rejections, StateError};
use rootfuse_attitude::registry::{AnyFilter, FilterSpec};
use rootfuse_attitude::{Dof, ImuSample, Lane, Mask, OrientationFilter, Vec3};
use rootfuse_batch::{Precision, RejectionTotals};
use std::sync::{Mutex, MutexGuard, PoisonError, TryLockError};

/// Parses `precision` ("f32" or "f64").
pub fn precision(text: &str) -> PyResult<Precision> {
    match text {
        "f32" | "float32" => Ok(Precision::F32),
        "f64" | "float64" => Ok(Precision::F64),
        _ => Err(PyValueError::new_err(format!(
            "precision: expected \"f32\" or \"f64\", got {text:?}"
        ))),
    }
}

/// Builds a validated spec from a name, `dof` and keyword parameters (registry checks).
pub fn spec_from(
    name: &str,
    dof: Option<DofArg>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<FilterSpec> {
    let mut spec =
        FilterSpec::new(name).map_err(|e| PyValueError::new_err(format!("name: {e}")))?;
    if let Some(params) = params {
        let kind = spec.kind();
        for (key, value) in params.iter() {
            let key: String = key.extract()?;
            // Names are exact: the registry's `key=value` text would trim " kp " to `kp`.
            // (`dof` goes to the registry, which says which filters have one.)
            let info = kind.params().iter().find(|p| p.name == key);
            if info.is_none() && key != "dof" {
                let valid: Vec<&str> = kind.params().iter().map(|p| p.name).collect();
                let hint = if key.trim() != key {
                    " (parameter names are exact: no spaces)"
                } else {
                    ""
                };
                return Err(PyValueError::new_err(format!(
                    "{key}: unknown parameter {key:?} of {}{hint} (valid: {})",
                    kind.name(),
                    valid.join(", ")
                )));
            }
            if value.is_instance_of::<pyo3::types::PyString>() {
                return Err(PyTypeError::new_err(format!(
                    "{key}: expected a number, got a string"
                )));
            }
            // A switch (0 or 1) takes a bool; anywhere else a bool is a mistake (`kp=True`).
            let switch = info.is_some_and(|p| matches!(p.kind, ParamKind::Switch));
            if !switch && arrays::is_bool(&value) {
                return Err(PyTypeError::new_err(format!(
                    "{key}: expected a number, got a bool ({}): booleans are not numbers here",
                    arrays::shown(&value)
                )));
            }
            let v: f64 = value.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "{key}: expected a number, got {}",
                    value
                        .get_type()
                        .name()
                        .map_or("?".into(), |n| n.to_string())
                ))
            })?;
            // `{:?}` is the shortest text that parses back to the same f64.
            spec.set(&format!("{key}={v:?}"))
                .map_err(|e| PyValueError::new_err(format!("{key}: {e}")))?;
        }
    }
    if let Some(DofArg(d)) = dof {
        let d = Dof::from_count(d)
            .ok_or_else(|| PyValueError::new_err(format!("dof: expected 6 or 9, got {d}")))?;
        // `set`, not `set_dof`: a filter without a 6D/9D choice (`gyro`) refuses the dof
        // instead of ignoring it.
        spec.set(&format!("dof={}", d.count()))
            .map_err(|e| PyValueError::new_err(format!("dof: {e}")))?;
    }
    Ok(spec)
}

/// Lane 0's counters.
fn totals<T: Lane>(r: &Rejections<T>) -> RejectionTotals {
    RejectionTotals::of_lane(r, 0)
}

/// What `update_batch` collects, flat, C order.
#[derive(Default)]
struct Series {
    quat: Vec<f64>,
    bias: Vec<f64>,
    cov: Vec<f64>,
    flags: Vec<u8>,
}

#[inline]
fn widen<T: Lane>(x: T) -> f64 {
    x.extract(0).into()
}

/// One step of `filter` on sample `s` (converted to `T` by rounding once), returning its flags.
#[inline]
fn step<T: Lane>(filter: &mut AnyFilter<T>, s: &ImuSample<f64>, dt: f64) -> u8 {
    let c = |v: Vec3<f64>| Vec3::<T>::from_f64([v.x, v.y, v.z]);
    filter.update(
        &ImuSample::new(c(s.gyr), c(s.acc), c(s.mag)),
        T::from_f64(dt),
    );
    filter.flags().bits(0)
}

/// The filter loop of `update_batch`, without the GIL.
fn run_series<T: Lane>(filter: &mut AnyFilter<T>, input: &Inputs<'_>, with_cov: bool) -> Series {
    let n = input.len;
    let mut out = Series {
        quat: Vec::with_capacity(4 * n),
        bias: Vec::with_capacity(3 * n),
        cov: Vec::with_capacity(if with_cov { 9 * n } else { 0 }),
        flags: Vec::with_capacity(n),
    };
    // The samples come a tile at a time through the batch engine's reader (one pass over
    // each array, float32 read as it is), the same values `step` would convert one by one.
    let mut tile: Vec<(ImuSample<T>, T)> = Vec::with_capacity(rootfuse_batch::TILE_STEPS);
    for i in 0..n {
        let j = i % rootfuse_batch::TILE_STEPS;
        if j == 0 {
            let len = (n - i).min(rootfuse_batch::TILE_STEPS);
            tile.clear();
            tile.resize(
                len,
                (
                    ImuSample::new(Vec3::zero(), Vec3::zero(), Vec3::zero()),
                    T::zero(),
                ),
            );
            rootfuse_batch::ChannelSource::read_into(input, i, 0, &mut tile);
        }
        let (sample, dt) = &tile[j];
        filter.update(sample, *dt);
        let f = filter.flags().bits(0);
        out.flags.push(f);
        let q = filter.quat();
        out.quat
            .extend_from_slice(&[widen(q.w), widen(q.x), widen(q.y), widen(q.z)]);
        let b = filter.bias();
        out.bias
            .extend_from_slice(&[widen(b.x), widen(b.y), widen(b.z)]);
        if with_cov {
            match filter.attitude_covariance() {
                Some(p) => out.cov.extend(p.m.iter().flatten().map(|&x| widen(x))),
                None => out.cov.extend([f64::NAN; 9]),
            }
        }
    }
    out
}

/// The filter in its precision. One per Python object, updated in place, so the size of the
/// larger variant costs nothing worth a box.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
enum State {
    F32(AnyFilter<f32>),
    F64(AnyFilter<f64>),
}

macro_rules! with_state {
    ($state:expr, $f:ident => $body:expr) => {
        match $state {
            State::F32($f) => $body,
            State::F64($f) => $body,
        }
    };
}

/// An orientation filter from the registry, by name, in f32 or f64.
///
/// `Filter(name, *, dof=None, precision="f64", **params)`: `name` is a registered filter
/// (`filters()` lists them, with every parameter, its unit, default and range; `"flagship"`
/// is `"sqrt-eskf"`); parameters are keyword arguments validated by the registry (a
/// ValueError names the parameter and the accepted range; names are exact, a bool is no
/// number); `dof` (keyword only) 6 (gyroscope and accelerometer) or 9 (with magnetometer;
/// the default of filters that have the choice; `gyro` has none, and a `dof` for it is a
/// ValueError).
///
/// Conventions: quaternions `[w, x, y, z]`, sensor to earth, earth ENU; gyroscope rad/s,
/// accelerometer m/s² (+g up at rest), magnetometer µT (the filters use the field's
/// direction; the screening limit `max_mag`, 1000, is in µT), time s. The
/// first samples of a stream (`update_batch`, `update`) are checked against these units, as
/// `rootfuse run` checks a file: readings that look like °/s, g, ms or nT give a
/// `UserWarning` naming the sensor and the unit they fit, once per sensor until `reset()`.
///
/// A Filter is used by one thread at a time: while `update_batch` runs (the GIL released),
/// any call on the same Filter from another thread is a RuntimeError. Make one Filter per
/// thread.
#[pyclass(frozen, module = "rootfuse._rootfuse")]
pub struct Filter {
    spec: FilterSpec,
    precision: Precision,
    /// The filter, locked by the call using it (`update_batch` holds it without the GIL).
    state: Mutex<State>,
    /// The last sample time of the last `update_batch(t=...)`, s: the next call with `t`
    /// continues from it. Locked only while `state` is held.
    last_time: Mutex<Option<f64>>,
    /// The unit check of the stream of calls (`update_batch`, `update`) since construction or
    /// `reset()`. Locked only while `state` is held.
    units: Mutex<StreamCheck>,
}

/// What a second thread gets instead of pyo3's "Already borrowed".
const BUSY: &str = "a Filter is used by one thread at a time (another thread is running this one, e.g. in update_batch, which releases the GIL): make one Filter per thread";

impl Filter {
    fn build(spec: FilterSpec, precision: Precision) -> Self {
        let state = Self::fresh(&spec, precision);
        Self {
            spec,
            precision,
            state: Mutex::new(state),
            last_time: Mutex::new(None),
            units: Mutex::new(StreamCheck::default()),
        }
    }
    fn fresh(spec: &FilterSpec, precision: Precision) -> State {
        match precision {
            Precision::F32 => State::F32(spec.build()),
            Precision::F64 => State::F64(spec.build()),
        }
    }
    /// The state, or the RuntimeError [`BUSY`] while another thread holds it. A panic in an
    /// earlier call left the state as it was then: it is used as it is.
    fn lock(&self) -> PyResult<MutexGuard<'_, State>> {
        match self.state.try_lock() {
            Ok(state) => Ok(state),
            Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
            Err(TryLockError::WouldBlock) => Err(PyRuntimeError::new_err(BUSY)),
        }
    }
    fn kind_name(&self) -> &'static str {
        self.spec.kind().name()
    }
    fn precision_name(&self) -> &'static str {
        match self.precision {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
    /// Reads a call's samples into the stream's unit check while it reads, and warns of what
    /// it finds before the filter runs. The check is updated only when every warning went
    /// out: one raised as an error leaves it (and the filter) as they were.
    fn check_units(&self, py: Python<'_>, input: &Inputs<'_>) -> PyResult<()> {
        let mut units = self.units.lock().unwrap_or_else(PoisonError::into_inner);
        if units.settled() {
            return Ok(());
        }
        let judged = Judged::of(&self.spec, false);
        let mut check = units.clone();
        py.detach(|| check.add_inputs(input, judged.field()));
        // A call of a few samples (a stream fed one by one) is judged now and then, as
        // `update` judges, a call of many at once.
        let every = if input.len >= 50 { 1 } else { JUDGE_EVERY };
        let findings = check.findings(&judged, every, false);
        deliver(py, "update_batch", &findings, &mut units)?;
        check.mark_warned(&findings);
        *units = check;
        Ok(())
    }
    fn dof_count(&self) -> Option<u8> {
        self.spec.dof().map(Dof::count)
    }
    /// A standard deviation argument: a finite number ≥ 0 (not a bool).
    fn sigma(&self, obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
        if arrays::is_bool(obj) {
            return Err(PyTypeError::new_err(format!(
                "{name}: expected a standard deviation (a number), got a bool"
            )));
        }
        let x = arrays::real(obj)?;
        if !(x.is_finite() && x >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "{name}: expected a standard deviation (a finite number ≥ 0), got {x}"
            )));
        }
        Ok(x)
    }
    /// The error for `sigma=` on a filter whose covariance cannot be set.
    /// What a refused state setter raises: ValueError for a value out of range; for a
    /// state the filter does not carry, ValueError when a `sigma` was given (it cannot be
    /// kept), `Ok(false)` otherwise (the documented "not taken").
    fn state_result(&self, r: Result<(), StateError>, sigma_given: bool) -> PyResult<bool> {
        match r {
            Ok(()) => Ok(true),
            Err(StateError::Unsupported(what)) if sigma_given => {
                Err(PyValueError::new_err(format!(
                    "sigma: `{}` carries no {what} (sqrt-eskf and ekf set their covariance with the state); call without sigma",
                    self.kind_name()
                )))
            }
            Err(StateError::Unsupported(_)) => Ok(false),
            Err(e) => Err(PyValueError::new_err(e.to_string())),
        }
    }
}

/// Reads `gyr`, `acc`, `mag` as `(N, 3)` arrays of one length.
pub fn imu_arrays<'py>(
    gyr: &Bound<'py, PyAny>,
    acc: &Bound<'py, PyAny>,
    mag: Option<&Bound<'py, PyAny>>,
) -> PyResult<(
    arrays::SensorArray<'py>,
    arrays::SensorArray<'py>,
    Option<arrays::SensorArray<'py>>,
    usize,
)> {
    let (gyr, n) = sensor_matrix(gyr, "gyr")?;
    let (acc, na) = sensor_matrix(acc, "acc")?;
    same_length("acc", na, n)?;
    let mag = match mag {
        Some(m) if !m.is_none() => {
            let (m, nm) = sensor_matrix(m, "mag")?;
            same_length("mag", nm, n)?;
            Some(m)
        }
        _ => None,
    };
    Ok((gyr, acc, mag, n))
}

fn vec3_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 3]> {
    // The per-sample path: a plain sequence of three numbers is read directly, without
    // building an error for the array path first.
    if obj.cast::<numpy::PyUntypedArray>().is_err() {
        let v = obj.extract::<[f64; 3]>().map_err(|_| {
            let len = obj
                .len()
                .map_or(String::new(), |n| format!(", got {n} values"));
            if obj.len().is_ok() && obj.extract::<Vec<f64>>().is_ok() {
                PyValueError::new_err(format!("{name}: expected 3 values (x, y, z){len}"))
            } else {
                PyTypeError::new_err(format!("{name}: expected three numbers"))
            }
        })?;
        arrays::no_bool_items(obj, name)?;
        return Ok(v);
    }
    let a = arrays::float_array(obj, name)?;
    match a.as_slice() {
        [x, y, z] if a.shape.len() == 1 => Ok([*x, *y, *z]),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected 3 values (x, y, z), got shape {:?}",
            a.shape
        ))),
    }
}

fn quat_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 4]> {
    let v: Vec<f64> = match arrays::float_array(obj, name) {
        Ok(a) if a.shape.len() == 1 => a.into_vec(),
        Ok(a) => {
            return Err(PyValueError::new_err(format!(
                "{name}: expected 4 values [w, x, y, z], got shape {:?}",
                a.shape
            )));
        }
        Err(_) => {
            let v: Vec<f64> = obj
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("{name}: expected four numbers")))?;
            arrays::no_bool_items(obj, name)?;
            v
        }
    };
    match v.as_slice() {
        [w, x, y, z] if v.iter().all(|c| c.is_finite()) && v.iter().any(|&c| c != 0.0) => {
            Ok([*w, *x, *y, *z])
        }
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected 4 finite values [w, x, y, z], not all zero, got {v:?}"
        ))),
    }
}

#[pymethods]
impl Filter {
    #[new]
    #[pyo3(signature = (name, *, dof=None, precision="f64", **params))]
    fn new(
        name: &str,
        dof: Option<DofArg>,
        precision: &str,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let spec = spec_from(name, dof, params)?;
        Ok(Self::build(spec, self::precision(precision)?))
    }

    /// The registered name of the filter (`"flagship"` gives `"sqrt-eskf"`).
    #[getter]
    fn name(&self) -> &'static str {
        self.kind_name()
    }

    /// `"f32"` or `"f64"`.
    #[getter]
    fn precision(&self) -> &'static str {
        self.precision_name()
    }

    /// 6 or 9 (None for `gyro`, which never reads the magnetometer).
    #[getter]
    fn dof(&self) -> Option<u8> {
        self.dof_count()
    }

    /// Every parameter's current value, `{name: value}` (units: see `filters()`).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in self.spec.kind().params() {
            if let Some(v) = self.spec.get(p.name) {
                // Whole-number kinds as Python ints, so that `Filter(name, **f.params)`
                // takes them back (`dof=9.0` is refused, as a fraction would be).
                let whole =
                    !matches!(p.kind, ParamKind::Real) && v.fract() == 0.0 && v.abs() < 1e15;
                if whole {
                    d.set_item(p.name, v as i64)?;
                } else {
                    d.set_item(p.name, v)?;
                }
            }
        }
        Ok(d)
    }

    /// Processes whole arrays from the current state, with the GIL released.
    ///
    /// gyr, acc, mag: `(N, 3)` float32/float64 arrays (rad/s, m/s², µT); `mag=None`
    /// for 6D data (a 9D filter then skips its magnetometer correction at every sample and
    /// flags it). Exactly one of `dt` (s: a number, or `(N,)` per sample: the step before
    /// each sample) and `t` (s, `(N,)`: the step before sample i is `t[i] − t[i−1]`, before
    /// sample 0 `t[1] − t[0]`, as `rootfuse run` does). A call with `t` right after a call
    /// with `t` continues its times: the step before its first sample is `t[0]` minus the
    /// last time of that call, so a stream fed in chunks runs as the whole array would (a
    /// call with `dt`, `update()` and `reset()` end the stream). Input is rounded to the
    /// filter's precision once.
    ///
    /// Returns a dict of float64 arrays: `quat` `(N, 4)` `[w, x, y, z]` after each sample;
    /// `bias` `(N, 3)` gyro-bias estimate, rad/s (zeros for filters without one);
    /// `covariance` `(N, 3, 3)` attitude-error covariance, rad², earth frame (only for filters
    /// that carry one: `sqrt-eskf`, `ekf`, ...; `covariance=False` leaves it out, 72 bytes
    /// a sample); `flags` `(N,)` uint8 per sample: 1 dt, 2 gyroscope (whole sample skipped),
    /// 4 accelerometer, 8 magnetometer (correction skipped), 16 gated by the filter, 32 at
    /// rest, 64 magnetic disturbance. NaN/inf inside the arrays are not errors: that sample
    /// (or correction) is skipped and flagged. Where most steps of a call (ten or more) will
    /// be skipped (not positive or beyond `max_dt`), a `UserWarning` says the likely cause
    /// (sample times given as `dt`, times in ms) before the filter runs. Until the stream's
    /// unit check has decided (at most 200 000 samples; about 100 ns a sample it reads), its samples are
    /// also read by it, and a sensor whose readings do not fit the units above is named in a
    /// `UserWarning` before the filter runs.
    #[pyo3(signature = (gyr, acc, mag=None, dt=None, *, t=None, covariance=true))]
    #[allow(clippy::too_many_arguments)]
    fn update_batch<'py>(
        &self,
        py: Python<'py>,
        gyr: &Bound<'py, PyAny>,
        acc: &Bound<'py, PyAny>,
        mag: Option<&Bound<'py, PyAny>>,
        dt: Option<&Bound<'py, PyAny>>,
        t: Option<&Bound<'py, PyAny>>,
        covariance: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (gyr, acc, mag, n) = imu_arrays(gyr, acc, mag)?;
        let steps = Steps::parse(dt, t, n)?;
        let mut guard = self.lock()?;
        let mut last_time = self
            .last_time
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let (steps, end) = steps.continuing(*last_time);
        let max_dt = self.spec.get("max_dt").unwrap_or(f64::INFINITY);
        warn_if_most_steps_skipped(py, "update_batch", steps.borrowed(), n, max_dt)?;
        let input = Inputs::new(&gyr, &acc, mag.as_ref(), &steps, n);
        self.check_units(py, &input)?;
        *last_time = end;
        drop(last_time);
        let state: &mut State = &mut guard;
        let with_cov = covariance && has_covariance(state);
        let series = py.detach(|| with_state!(state, f => run_series(f, &input, with_cov)));
        drop(guard);
        let out = PyDict::new(py);
        out.set_item("quat", PyArray1::from_vec(py, series.quat).reshape([n, 4])?)?;
        out.set_item("bias", PyArray1::from_vec(py, series.bias).reshape([n, 3])?)?;
        if with_cov {
            out.set_item(
                "covariance",
                PyArray1::from_vec(py, series.cov).reshape([n, 3, 3])?,
            )?;
        }
        out.set_item("flags", PyArray1::from_vec(py, series.flags))?;
        Ok(out)
    }

    /// One sample: gyr, acc (and mag for 9D) as 3 numbers each (rad/s, m/s², µT), dt
    /// the step before it, s. Returns the sample's flags (bits as in `update_batch`); the
    /// state is in `quat`, `bias`, `covariance`. NaN/inf values are skipped and flagged.
    #[pyo3(signature = (gyr, acc, mag=None, *, dt))]
    fn update(
        &self,
        gyr: &Bound<'_, PyAny>,
        acc: &Bound<'_, PyAny>,
        mag: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arrays::real)] dt: f64,
    ) -> PyResult<u8> {
        let g = vec3_arg(gyr, "gyr")?;
        let a = vec3_arg(acc, "acc")?;
        let s = match mag {
            Some(m) if !m.is_none() => {
                let m = vec3_arg(m, "mag")?;
                ImuSample::new(Vec3::from_f64(g), Vec3::from_f64(a), Vec3::from_f64(m))
            }
            _ => ImuSample::six_d(Vec3::from_f64(g), Vec3::from_f64(a)),
        };
        let mut state = self.lock()?;
        {
            let mut units = self.units.lock().unwrap_or_else(PoisonError::into_inner);
            let judged = Judged::of(&self.spec, false);
            let field = (judged.field() && mag.is_some_and(|m| !m.is_none())).then_some(s.mag);
            let max_dt = self.spec.screen_limits().max_dt;
            units.count_step(dt, max_dt);
            units.warn_of_first_steps(gyr.py(), "update", max_dt)?;
            units.add(dt, s.gyr, s.acc, field);
            let findings = units.findings(&judged, JUDGE_EVERY, false);
            if let Err(e) = deliver(gyr.py(), "update", &findings, &mut units) {
                units.judge_again();
                return Err(e);
            }
        }
        *self
            .last_time
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = None;
        Ok(with_state!(&mut *state, f => step(f, &s, dt)))
    }

    /// Current orientation `[w, x, y, z]` (sensor to earth, ENU), float64 `(4,)`.
    #[getter]
    fn quat<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let q = with_state!(&*self.lock()?, f => {
            let q = f.quat();
            [widen(q.w), widen(q.x), widen(q.y), widen(q.z)]
        });
        Ok(PyArray1::from_slice(py, &q))
    }

    /// Current gyro-bias estimate, rad/s, float64 `(3,)` (zeros for filters without one;
    /// `heading-pipeline` estimates the component about earth-up only).
    #[getter]
    fn bias<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let b = with_state!(&*self.lock()?, f => {
            let b = f.bias();
            [widen(b.x), widen(b.y), widen(b.z)]
        });
        Ok(PyArray1::from_slice(py, &b))
    }

    /// Current estimate of the gyroscope's scale error per sensor axis, a fraction `s` in
    /// `ω_measured = (1 + s)·ω`, float64 `(3,)`: the flagship's (`gyr_scale_window > 0`;
    /// zeros until its first window closes, 20 s with the defaults), zeros for the other
    /// filters.
    #[getter]
    fn gyro_scale<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let s = with_state!(&*self.lock()?, f => {
            let s = f.gyro_scale();
            [widen(s.x), widen(s.y), widen(s.z)]
        });
        Ok(PyArray1::from_slice(py, &s))
    }

    /// Current attitude-error covariance, rad², earth frame ENU (`[2, 2]` is heading),
    /// float64 `(3, 3)`; None for filters without one.
    #[getter]
    fn covariance<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, numpy::PyArray2<f64>>>> {
        let p = with_state!(&*self.lock()?, f => f
            .attitude_covariance()
            .map(|p| p.m.iter().flatten().map(|&x| widen(x)).collect::<Vec<f64>>()));
        Ok(p.and_then(|p| Array2::from_shape_vec((3, 3), p).ok())
            .map(|a| numpy::IntoPyArray::into_pyarray(a, py)))
    }

    /// What was skipped since the filter was built or reset, by reason:
    /// `{"dt", "gyr", "acc", "mag", "gated", "mag_disturbed"}` counts.
    #[getter]
    fn rejections<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = with_state!(&*self.lock()?, f => totals(f.rejections()));
        rejections_dict(py, &r)
    }

    /// Sets the orientation `[w, x, y, z]` (sensor to earth, ENU; normalised by the filter)
    /// and marks the filter initialised: the next samples correct from there instead of
    /// starting over from the accelerometer. Learned state (bias, covariance) is kept.
    /// `sigma` (rad; sqrt-eskf and ekf, the filters with a covariance): the orientation's
    /// standard deviation per earth axis; `covariance()` then reads `sigma²·I` (the
    /// attitude–bias correlation removed).
    #[pyo3(signature = (q, sigma=None))]
    fn set_quat(&self, q: &Bound<'_, PyAny>, sigma: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let q = quat_arg(q, "q")?;
        // Normalising a quaternion far from unit norm hides a mistake (a vector of tiny
        // numbers became the identity in f32).
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(0.5..=2.0).contains(&norm) {
            return Err(PyValueError::new_err(format!(
                "q: norm {norm:.3e} is far from 1: expected a unit quaternion [w, x, y, z] (a small deviation is normalised)"
            )));
        }
        let sigma = sigma.map(|s| self.sigma(s, "sigma")).transpose()?;
        let mut state = self.lock()?;
        let r = with_state!(&mut *state, f => {
            f.set_quat(rootfuse_attitude::Quat::from_f64(q), sigma.map(Lane::from_f64))
        });
        // A quaternion without a sigma is taken by every filter.
        self.state_result(r, sigma.is_some()).map(|_| ())
    }

    /// Sets the gyro-bias estimate, rad/s (sensor frame, 3 numbers), kept from there (also
    /// before the first sample). Returns False (and changes nothing) for filters without a
    /// bias estimate (`gyro`, `complementary`) and for `heading-pipeline`, whose estimate is
    /// one component (the heading rate about earth-up) and cannot hold a three-axis bias.
    /// `complementary-reconstruction` takes it in place of its still-period mean once the
    /// still period (`still_s`) is over, False during it (the mean is being taken);
    /// `lsq-fusion` clamps it to `drift_max`, as every estimate of its drift.
    /// `sigma` (rad/s; sqrt-eskf, ekf and ecf-ekf): the bias's standard deviation per axis,
    /// set with it. A component above 1 rad/s is refused (no gyro bias is that large).
    #[pyo3(signature = (bias, sigma=None))]
    fn set_bias(
        &self,
        bias: &Bound<'_, PyAny>,
        sigma: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        let b = vec3_arg(bias, "bias")?;
        if !b.iter().all(|x| x.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "bias: expected finite values, got {b:?}"
            )));
        }
        // Checked in the filter's precision: 1e39 is finite in f64 and infinite in f32.
        if self.precision == Precision::F32 && b.iter().any(|x| x.abs() > f64::from(f32::MAX)) {
            return Err(PyValueError::new_err(format!(
                "bias: {b:?} is not representable in this f32 filter (|value| > {:e}): expected rad/s",
                f32::MAX
            )));
        }
        let sigma = sigma.map(|s| self.sigma(s, "sigma")).transpose()?;
        let mut state = self.lock()?;
        let r = with_state!(&mut *state, f => {
            f.set_bias(Vec3::from_f64(b), sigma.map(Lane::from_f64))
        });
        self.state_result(r, sigma.is_some())
    }

    /// Turns the orientation about earth-up so that its heading (yaw, rad, counter-clockwise
    /// from north) becomes `heading`; the inclination is kept.
    fn set_heading(&self, #[pyo3(from_py_with = arrays::real)] heading: f64) -> PyResult<()> {
        if !heading.is_finite() {
            return Err(PyValueError::new_err(format!(
                "heading: expected a finite angle in rad, got {heading}"
            )));
        }
        let mut state = self.lock()?;
        let r = with_state!(&mut *state, f => f.set_heading(Lane::from_f64(heading)));
        self.state_result(r, false).map(|_| ())
    }

    /// The magnetometer's readings change from the next sample on for a reason that is not
    /// the field's (the caller now applies a new calibration to them): a filter that learns
    /// a field reference (`sqrt-eskf` in 9D) takes the next usable reading as its reference,
    /// pointing north, and its heading from it, instead of rejecting the new readings as a
    /// disturbance. Nothing for the other filters.
    fn forget_field_reference(&self) -> PyResult<()> {
        let mut state = self.lock()?;
        with_state!(&mut *state, f => f.forget_field_reference(Mask::splat(true)));
        Ok(())
    }

    /// Back to the state just after construction (same parameters and precision).
    fn reset(&self) -> PyResult<()> {
        let fresh = Self::fresh(&self.spec, self.precision);
        let mut state = self.lock()?;
        *state = fresh;
        *self
            .last_time
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = None;
        *self.units.lock().unwrap_or_else(PoisonError::into_inner) = StreamCheck::default();
        Ok(())
    }

    fn __repr__(&self) -> String {
        format!(
            "Filter({:?}, dof={}, precision={:?})",
            self.kind_name(),
            self.dof_count().map_or("None".into(), |d| d.to_string()),
            self.precision_name()
        )
    }
}

/// Whether the filter in `state` carries an attitude covariance.
fn has_covariance(state: &State) -> bool {
    with_state!(state, f => f.attitude_covariance().is_some())
}

/// The counters as a dict: `{"dt", "gyr", "acc", "mag", "gated", "mag_disturbed"}`.
pub fn rejections_dict<'py>(py: Python<'py>, r: &RejectionTotals) -> PyResult<Bound<'py, PyDict>> {
    RejectionDicts::new(py)?.dict(r)
}

/// [`rejections_dict`] for many channels: each dict a copy of one with every count zero (the
/// same keys in the same order), the counts that are not zero then set under interned keys:
/// built from six items and six new key strings each, the dicts were a tenth of `run_many`'s
/// time on 4096 channels of 2000 samples (docs/performance.md).
pub struct RejectionDicts<'py> {
    zeros: Bound<'py, PyDict>,
}

impl<'py> RejectionDicts<'py> {
    /// The all-zero dict the others copy.
    pub fn new(py: Python<'py>) -> PyResult<Self> {
        let zeros = PyDict::new(py);
        for (key, _) in Self::counts(py, &RejectionTotals::default()) {
            zeros.set_item(key, 0u64)?;
        }
        Ok(Self { zeros })
    }

    /// The dict of `r`'s counts.
    pub fn dict(&self, r: &RejectionTotals) -> PyResult<Bound<'py, PyDict>> {
        let d = self.zeros.copy()?;
        for (key, n) in Self::counts(self.zeros.py(), r) {
            if n != 0 {
                d.set_item(key, n)?;
            }
        }
        Ok(d)
    }

    fn counts<'a>(py: Python<'a>, r: &RejectionTotals) -> [(&'a Bound<'a, PyString>, u64); 6] {
        [
            (intern!(py, "dt"), r.dt),
            (intern!(py, "gyr"), r.gyr),
            (intern!(py, "acc"), r.acc),
            (intern!(py, "mag"), r.mag),
            (intern!(py, "gated"), r.gated),
            (intern!(py, "mag_disturbed"), r.mag_disturbed),
        ]
    }
}
