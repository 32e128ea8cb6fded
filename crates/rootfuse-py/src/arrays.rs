//! Reading NumPy arguments: dtype, shape and length checks with messages that name the
//! argument and what was expected. Nothing here panics on user data.

use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyInt};

/// A float array read from Python, as `f64` values in C order, with its shape.
///
/// A C-contiguous `float64` array is borrowed, not copied (the borrow is a slice, so the GIL
/// can be released while Rust reads it); `float32` arrays are widened exactly and
/// non-contiguous arrays are copied in C order. Other dtypes are a `TypeError`.
pub struct FloatArray<'py> {
    data: Data<'py>,
    /// The shape.
    pub shape: Vec<usize>,
}

enum Data<'py> {
    Borrowed(numpy::PyReadonlyArrayDyn<'py, f64>),
    Owned(Vec<f64>),
}

impl FloatArray<'_> {
    /// The values in C order.
    pub fn as_slice(&self) -> &[f64] {
        match &self.data {
            // `float_array` borrows only contiguous arrays, so this never falls back.
            Data::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Data::Owned(v) => v,
        }
    }
    /// The values in C order, owned.
    pub fn into_vec(self) -> Vec<f64> {
        match self.data {
            Data::Borrowed(a) => a.as_slice().map(<[f64]>::to_vec).unwrap_or_default(),
            Data::Owned(v) => v,
        }
    }
}

/// Sensor values as stored: float32 or float64, C order. Read with [`Floats::get`] or in
/// runs of rows; nothing is widened into a copy.
#[derive(Clone, Copy, Debug)]
pub enum Floats<'a> {
    /// float32 values.
    F32(&'a [f32]),
    /// float64 values.
    F64(&'a [f64]),
}

impl Floats<'_> {
    /// Value `i` in `f64` (exact), NaN past the end.
    #[inline]
    pub fn get(&self, i: usize) -> f64 {
        match self {
            Self::F32(v) => v.get(i).map_or(f64::NAN, |&x| f64::from(x)),
            Self::F64(v) => v.get(i).copied().unwrap_or(f64::NAN),
        }
    }

    /// Values `range` (clamped to the data).
    pub fn slice(&self, range: core::ops::Range<usize>) -> Self {
        let clamp = |len: usize| range.start.min(len)..range.end.min(len);
        match self {
            Self::F32(v) => Self::F32(&v[clamp(v.len())]),
            Self::F64(v) => Self::F64(&v[clamp(v.len())]),
        }
    }
}

/// A float32 or float64 array of sensor values, borrowed when C-contiguous (float32 is not
/// widened: [`Floats`]), otherwise copied in C order in its own precision.
pub struct SensorArray<'py> {
    data: SensorData<'py>,
    /// The shape.
    pub shape: Vec<usize>,
}

enum SensorData<'py> {
    F64(FloatArray<'py>),
    F32(numpy::PyReadonlyArrayDyn<'py, f32>),
    F32Owned(Vec<f32>),
}

impl SensorArray<'_> {
    /// The values in C order.
    pub fn floats(&self) -> Floats<'_> {
        match &self.data {
            SensorData::F64(a) => Floats::F64(a.as_slice()),
            // `sensor_array` borrows only C-contiguous arrays, so this never falls back.
            SensorData::F32(a) => Floats::F32(a.as_slice().unwrap_or(&[])),
            SensorData::F32Owned(v) => Floats::F32(v),
        }
    }
}

/// Reads `obj` (argument `name`) as a float32/float64 NumPy array of any shape, keeping its
/// precision (see [`SensorArray`]).
pub fn sensor_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<SensorArray<'py>> {
    if let Some(a) = c_order::<f32>(obj, name) {
        let (data, shape) = a?;
        let data = match data {
            Ok(ro) => SensorData::F32(ro),
            Err(copy) => SensorData::F32Owned(copy),
        };
        return Ok(SensorArray { data, shape });
    }
    let a = float_array(obj, name)?;
    let shape = a.shape.clone();
    Ok(SensorArray {
        data: SensorData::F64(a),
        shape,
    })
}

/// [`sensor_array`] copied, not borrowed, where it holds at most `max_values` values: a
/// C-contiguous, aligned array is copied without a borrow of the numpy crate's tracker (which
/// checks each new borrow against every other of the same base array, so borrowing thousands
/// of views of one array is quadratic); any other is read as [`sensor_array`] reads it.
pub fn sensor_array_copied<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    max_values: usize,
) -> PyResult<SensorArray<'py>> {
    let small = obj
        .cast::<PyUntypedArray>()
        .is_ok_and(|a| a.len() <= max_values);
    if small {
        if let Some((v, shape)) = copied_c_order::<f32>(obj) {
            return Ok(SensorArray {
                data: SensorData::F32Owned(v),
                shape,
            });
        }
        if let Some((v, shape)) = copied_c_order::<f64>(obj) {
            let data = SensorData::F64(FloatArray {
                data: Data::Owned(v),
                shape: shape.clone(),
            });
            return Ok(SensorArray { data, shape });
        }
    }
    sensor_array(obj, name)
}

/// A C-contiguous, aligned `T` array copied (the numpy crate's `to_vec`, no borrow), with its
/// shape; `None` for anything else.
fn copied_c_order<T: numpy::Element + Copy>(
    obj: &Bound<'_, PyAny>,
) -> Option<(Vec<T>, Vec<usize>)> {
    let a = obj.cast::<PyArrayDyn<T>>().ok()?;
    if !(a.is_c_contiguous() && is_aligned(a)) {
        return None;
    }
    Some((a.to_vec().ok()?, a.shape().to_vec()))
}

/// Whether the array's memory is aligned for `T` (an array over a buffer may not be, and a
/// slice must be).
fn is_aligned<T: numpy::Element>(a: &Bound<'_, PyArrayDyn<T>>) -> bool {
    (a.data() as usize).is_multiple_of(std::mem::align_of::<T>())
}

/// A `T` array borrowed as it is when C-contiguous (`Ok`), else copied in C order (`Err`),
/// with its shape; `None` when `obj` is not an array of `T`.
#[allow(clippy::type_complexity)]
fn c_order<'py, T: numpy::Element + Copy>(
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> Option<
    PyResult<(
        Result<numpy::PyReadonlyArrayDyn<'py, T>, Vec<T>>,
        Vec<usize>,
    )>,
> {
    let a = obj.cast::<PyArrayDyn<T>>().ok()?;
    let shape = a.shape().to_vec();
    let ro = match a.try_readonly() {
        Ok(ro) => ro,
        Err(e) => {
            return Some(Err(PyValueError::new_err(format!(
                "{name}: the array cannot be borrowed ({e})"
            ))));
        }
    };
    // `as_slice` also accepts Fortran order, whose memory is not C order, and unaligned
    // memory (an array over a buffer), which a slice must not be: check both first.
    let data = if a.is_c_contiguous() && is_aligned(a) && ro.as_slice().is_ok() {
        Ok(ro)
    } else {
        Err(ro.as_array().iter().copied().collect())
    };
    Some(Ok((data, shape)))
}

pub(crate) fn dtype_name(obj: &Bound<'_, PyAny>) -> String {
    obj.getattr("dtype")
        .and_then(|d| d.str().map(|s| s.to_string()))
        .unwrap_or_else(|_| obj.get_type().name().map_or("?".into(), |n| n.to_string()))
}

/// Reads `obj` (argument `name`) as a float32/float64 NumPy array of any shape.
pub fn float_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<FloatArray<'py>> {
    if let Some(a) = c_order::<f64>(obj, name) {
        let (data, shape) = a?;
        let data = match data {
            Ok(ro) => Data::Borrowed(ro),
            Err(copy) => Data::Owned(copy),
        };
        return Ok(FloatArray { data, shape });
    }
    if let Some(a) = c_order::<f32>(obj, name) {
        let (data, shape) = a?;
        let wide = match &data {
            Ok(ro) => ro.as_array().iter().map(|&x| f64::from(x)).collect(),
            Err(copy) => copy.iter().map(|&x| f64::from(x)).collect(),
        };
        return Ok(FloatArray {
            data: Data::Owned(wide),
            shape,
        });
    }
    if obj.cast::<numpy::PyUntypedArray>().is_ok() {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected a float32 or float64 numpy array, got dtype {}",
            dtype_name(obj)
        )));
    }
    Err(PyTypeError::new_err(format!(
        "{name}: expected a numpy array of float32 or float64, got {}",
        obj.get_type().name().map_or("?".into(), |n| n.to_string())
    )))
}

pub(crate) fn shape_text(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// `obj` as an `(N, cols)` array; returns the values and `N`.
pub fn matrix<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    cols: usize,
) -> PyResult<(FloatArray<'py>, usize)> {
    let a = float_array(obj, name)?;
    match *a.shape.as_slice() {
        [n, c] if c == cols => Ok((a, n)),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, {cols}), got {}",
            shape_text(&a.shape)
        ))),
    }
}

/// `obj` as an `(N, 3)` sensor array in its own precision; returns it and `N`.
pub fn sensor_matrix<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<(SensorArray<'py>, usize)> {
    let a = sensor_array(obj, name)?;
    match *a.shape.as_slice() {
        [n, 3] => Ok((a, n)),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, 3), got {}",
            shape_text(&a.shape)
        ))),
    }
}

/// `obj` as a one-dimensional array.
pub fn vector(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    let a = float_array(obj, name)?;
    let shape = a.shape.clone();
    match shape.as_slice() {
        [_] => Ok(a.into_vec()),
        s => Err(PyValueError::new_err(format!(
            "{name}: expected shape (N,), got {}",
            shape_text(s)
        ))),
    }
}

/// `obj` as a square `(n, n)` array.
pub fn square(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<f64>> {
    let a = float_array(obj, name)?;
    let shape = a.shape.clone();
    match shape.as_slice() {
        [r, c] if *r == n && *c == n => Ok(a.into_vec()),
        s => Err(PyValueError::new_err(format!(
            "{name}: expected shape ({n}, {n}), got {}",
            shape_text(s)
        ))),
    }
}

/// The text of `obj` for a message (its `repr`).
pub(crate) fn shown(obj: &Bound<'_, PyAny>) -> String {
    obj.repr().map_or_else(|_| "?".into(), |r| r.to_string())
}

/// The name of `obj`'s type, for a message.
pub(crate) fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "?".into(), |n| n.to_string())
}

/// True for Python's `bool` and NumPy's `bool_`. Both convert to numbers (`float(True)` is
/// 1.0), but a flag where a number is meant (`kp=True`, `dt=True`) is a mistake, refused.
pub fn is_bool(obj: &Bound<'_, PyAny>) -> bool {
    if obj.is_instance_of::<PyBool>() {
        return true;
    }
    if obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>() {
        return false;
    }
    // numpy.bool_ ("bool" in NumPy 2, "bool_" in NumPy 1) is no subclass of either.
    obj.get_type()
        .name()
        .is_ok_and(|n| matches!(n.to_string().as_str(), "bool" | "bool_"))
}

/// The TypeError for a bool given where a number is meant (pyo3 puts `argument 'name': `
/// before it for a function argument).
fn bool_given(obj: &Bound<'_, PyAny>, expected: &str) -> PyErr {
    PyTypeError::new_err(format!(
        "expected {expected}, got a bool ({}): booleans are not numbers here",
        shown(obj)
    ))
}

/// A real-number argument (`#[pyo3(from_py_with = real)]`): an int, a float or a NumPy
/// scalar; a bool is a TypeError naming the argument.
pub fn real(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    if is_bool(obj) {
        return Err(bool_given(obj, "a number"));
    }
    obj.extract::<f64>()
}

/// [`real`] or None.
pub fn real_or_none(obj: &Bound<'_, PyAny>) -> PyResult<Option<f64>> {
    if obj.is_none() {
        Ok(None)
    } else {
        real(obj).map(Some)
    }
}

/// A count argument (`#[pyo3(from_py_with = whole)]`): a non-negative int; a bool is a
/// TypeError naming the argument.
pub fn whole(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    if is_bool(obj) {
        return Err(bool_given(obj, "a whole number"));
    }
    obj.extract::<usize>()
}

/// Refuses bools among the items of a sequence of numbers `name` (`[True, 0, 0]`).
pub fn no_bool_items(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    for (i, item) in obj.try_iter()?.enumerate() {
        let item = item?;
        if is_bool(&item) {
            return Err(PyTypeError::new_err(format!(
                "{name}[{i}]: expected a number, got a bool ({}): booleans are not numbers here",
                shown(&item)
            )));
        }
    }
    Ok(())
}

/// Refuses a square matrix `m` (`n`×`n`, C order) that is not symmetric: the worst pair must
/// agree to 1e-9 of the largest magnitude. Only one triangle would be read, silently.
/// Non-finite entries are left to the solver, which names their position.
pub fn symmetric(m: &[f64], n: usize, name: &str) -> PyResult<()> {
    let scale = m
        .iter()
        .filter(|x| x.is_finite())
        .fold(0.0_f64, |a, &x| a.max(x.abs()));
    let mut worst = (0.0_f64, 0, 0);
    for i in 0..n {
        for j in i + 1..n {
            let d = (m[i * n + j] - m[j * n + i]).abs();
            if d > worst.0 {
                worst = (d, i, j);
            }
        }
    }
    let (d, i, j) = worst;
    if d.is_finite() && d > SYMMETRY_TOLERANCE * scale {
        return Err(PyValueError::new_err(format!(
            "{name}: not symmetric: [{i}, {j}] = {} but [{j}, {i}] = {} (difference {d:.3e}, {:.1e} of the largest entry {scale:.3e}; tolerance {SYMMETRY_TOLERANCE:.0e}): give a symmetric matrix, e.g. (a + a.T) / 2",
            m[i * n + j],
            m[j * n + i],
            d / scale
        )));
    }
    Ok(())
}

/// Relative asymmetry [`symmetric`] accepts.
pub const SYMMETRY_TOLERANCE: f64 = 1e-9;

/// The `dof` argument: 6 or 9. Anything else (another integer, a negative or huge one, a
/// float) is a ValueError naming `dof`: pyo3's own conversion to `u8` raised a bare
/// OverflowError that named nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DofArg(pub u8);

impl<'a, 'py> FromPyObject<'a, 'py> for DofArg {
    type Error = PyErr;
    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if is_bool(&obj) {
            return Err(bool_given(&obj, "6 or 9"));
        }
        match obj.extract::<i64>() {
            Ok(d @ (6 | 9)) => Ok(Self(d as u8)),
            _ => Err(PyValueError::new_err(format!(
                "dof: expected 6 or 9, got {}",
                shown(&obj)
            ))),
        }
    }
}

/// A seed: a whole number in `[0, 2**64)`; anything else is a ValueError naming `seed`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SeedArg(pub u64);

impl<'a, 'py> FromPyObject<'a, 'py> for SeedArg {
    type Error = PyErr;
    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if is_bool(&obj) {
            return Err(bool_given(&obj, "a whole number in [0, 2**64)"));
        }
        obj.extract::<u64>().map(Self).map_err(|_| {
            PyValueError::new_err(format!(
                "seed: expected a whole number in [0, 2**64), got {}",
                shown(&obj)
            ))
        })
    }
}

/// Checks that `got` samples of argument `name` agree with the `n` of `gyr`.
pub fn same_length(name: &str, got: usize, n: usize) -> PyResult<()> {
    if got == n {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "{name}: has {got} samples but gyr has {n}; every per-sample argument must have the same length"
        )))
    }
}

/// A finite, positive scalar argument.
pub fn positive(value: f64, name: &str) -> PyResult<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name}: expected a finite number > 0, got {value}"
        )))
    }
}

/// What `dt` may be, for messages.
const DT_EXPECTED: &str =
    "expected a number (the step, s) or a 1-D float array of per-sample steps (s)";

/// The time step before each sample, from one of `dt` (scalar or per sample) or `t`.
#[derive(Clone, Debug)]
pub enum Steps {
    /// The same step before every sample, s.
    Fixed(f64),
    /// The step before each sample, s.
    PerSample(Vec<f64>),
    /// Sample times, s: the step before sample `i > 0` is `t[i] − t[i−1]`, before sample 0
    /// `t[1] − t[0]` (as `rootfuse_attitude::Recording::dt`).
    Times(Vec<f64>),
}

/// A channel's sampling as [`Steps`] says it, over values borrowed from it or from a NumPy
/// array (`run_many`'s `(C, N)` `t` or `dt`, each channel a row: read in place where it is
/// float64 in C order, converted once, whole, otherwise).
#[derive(Clone, Copy, Debug)]
pub enum StepsRef<'a> {
    /// The same step before every sample, s.
    Fixed(f64),
    /// The step before each sample, s.
    PerSample(&'a [f64]),
    /// Sample times, s (the steps as in [`Steps::Times`]).
    Times(&'a [f64]),
}

impl StepsRef<'_> {
    /// The step before sample `i`, s (non-finite or non-positive steps are passed on: the
    /// filter skips such a sample and flags it).
    #[inline]
    pub fn at(&self, i: usize) -> f64 {
        match *self {
            Self::Fixed(dt) => dt,
            Self::PerSample(v) => v[i],
            Self::Times(t) => match i {
                _ if t.len() < 2 => 0.0,
                0 => t[1] - t[0],
                _ => t[i] - t[i - 1],
            },
        }
    }
}

impl Steps {
    /// Reads `dt` / `t` (exactly one must be given) for `n` samples.
    pub fn parse(
        dt: Option<&Bound<'_, PyAny>>,
        t: Option<&Bound<'_, PyAny>>,
        n: usize,
    ) -> PyResult<Self> {
        match (dt, t) {
            (Some(_), Some(_)) => Err(PyValueError::new_err(
                "dt, t: give either dt (scalar or per sample) or t (sample times), not both",
            )),
            (None, None) => Err(PyValueError::new_err(
                "dt, t: missing the sampling: give dt (s, scalar or shape (N,)) or t (s, shape (N,))",
            )),
            (Some(dt), None) => {
                if dt.cast::<numpy::PyUntypedArray>().is_err() {
                    if is_bool(dt) {
                        return Err(PyTypeError::new_err(format!(
                            "dt: {DT_EXPECTED}, got a bool ({}): booleans are not numbers here",
                            shown(dt)
                        )));
                    }
                    return match dt.extract::<f64>() {
                        Ok(x) => Ok(Self::Fixed(positive(x, "dt")?)),
                        Err(_) => Err(PyTypeError::new_err(format!(
                            "dt: {DT_EXPECTED}, got {}",
                            type_name(dt)
                        ))),
                    };
                }
                let v = vector(dt, "dt")?;
                same_length("dt", v.len(), n)?;
                Ok(Self::PerSample(v))
            }
            (None, Some(t)) => {
                let v = vector(t, "t")?;
                same_length("t", v.len(), n)?;
                Ok(Self::Times(v))
            }
        }
    }

    /// These steps as the next call of a stream whose last sample time was `previous` (s):
    /// sample times then take `t[0] − previous` as the step before their first sample;
    /// steps given as `dt` are kept. Also returns the last sample time for the call after
    /// (`None` where the steps are not times: `dt` ends a stream).
    pub fn continuing(self, previous: Option<f64>) -> (Self, Option<f64>) {
        match (self, previous) {
            (Self::Times(t), Some(p)) if !t.is_empty() => {
                let end = t.last().copied();
                let steps = (0..t.len())
                    .map(|i| t[i] - if i == 0 { p } else { t[i - 1] })
                    .collect();
                (Self::PerSample(steps), end)
            }
            (Self::Times(t), previous) => {
                let end = t.last().copied().or(previous);
                (Self::Times(t), end)
            }
            (steps, _) => (steps, None),
        }
    }

    /// The same steps, borrowed.
    pub fn borrowed(&self) -> StepsRef<'_> {
        match self {
            Self::Fixed(dt) => StepsRef::Fixed(*dt),
            Self::PerSample(v) => StepsRef::PerSample(v),
            Self::Times(t) => StepsRef::Times(t),
        }
    }

    /// Sample times for `n` samples: `t` as given, or `k·dt` for a fixed step, or the running
    /// sum of per-sample steps (starting at 0).
    pub fn times(&self, n: usize) -> Vec<f64> {
        match self {
            Self::Fixed(dt) => (0..n).map(|k| k as f64 * dt).collect(),
            Self::PerSample(v) => {
                let mut acc = 0.0;
                v.iter()
                    .enumerate()
                    .map(|(k, d)| {
                        if k > 0 {
                            acc += d;
                        }
                        acc
                    })
                    .collect()
            }
            Self::Times(t) => t.clone(),
        }
    }
}
