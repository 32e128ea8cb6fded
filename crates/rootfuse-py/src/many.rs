//! Many channels through the SIMD batch engine (`rootfuse_batch`), on all cores.
//!
//! Input arrays are borrowed as they are (float32 or float64, never widened into a copy) and
//! read by the engine a tile of samples per channel at a time
//! ([`ChannelSource::read_into`](rootfuse_batch::ChannelSource::read_into)); series are
//! written by the engine straight into NumPy arrays allocated once, or the caller's (`out`)
//! ([`EstimateSink`](rootfuse_batch::EstimateSink)).

use crate::arrays::{
    DofArg, Floats, SensorArray, Steps, StepsRef, float_array, is_bool, positive, sensor_array,
    sensor_array_copied, type_name, vector,
};
use crate::filter::{RejectionDicts, spec_from};
use crate::inputs::Inputs;
use crate::series_arrays::{ArraySink, SeriesArrays, SeriesFloat, SeriesViews};
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use rootfuse_attitude::OrientationFilter;
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_batch::{Columns, Precision, RejectionTotals, run_final_states, run_into_sinks};
use std::collections::HashMap;

/// Channels as given: one `(C, N, 3)` array, or a list of `(N_i, 3)` arrays.
struct Channels<'py> {
    /// One array per channel when a list was given; one array of all channels otherwise.
    arrays: Vec<SensorArray<'py>>,
    /// Samples of each channel.
    lens: Vec<usize>,
    /// True when the input was a `(C, N, 3)` array.
    stacked: bool,
}

impl Channels<'_> {
    fn channel(&self, c: usize) -> Floats<'_> {
        if self.stacked {
            let n = self.lens.first().copied().unwrap_or(0);
            self.arrays[0].floats().slice(c * n * 3..(c + 1) * n * 3)
        } else {
            self.arrays[c].floats()
        }
    }
}

fn is_sequence(obj: &Bound<'_, PyAny>) -> bool {
    obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>()
}

fn channels<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Channels<'py>> {
    if is_sequence(obj) {
        let mut arrays = Vec::new();
        let mut lens = Vec::new();
        // Short views of one array (a fleet cut from one table) past the first few are copied:
        // each borrow is checked against every other borrow of the same base, so borrowing
        // thousands of them would cost the square of their number. Long ones stay borrowed (no
        // second copy of a large input): their number is bounded by memory, and each one's
        // filtering outweighs its check.
        let mut views: HashMap<usize, usize> = HashMap::new();
        for (c, item) in obj.try_iter()?.enumerate() {
            let item = item?;
            let label = format!("{name}[{c}]");
            let base = item
                .getattr(intern!(item.py(), "base"))
                .ok()
                .filter(|b| !b.is_none())
                .map_or(item.as_ptr() as usize, |b| b.as_ptr() as usize);
            let seen = views.entry(base).or_insert(0);
            *seen += 1;
            let a = if *seen > BORROWED_VIEWS {
                sensor_array_copied(&item, &label, COPIED_VIEW_VALUES)?
            } else {
                sensor_array(&item, &label)?
            };
            match *a.shape.as_slice() {
                [n, 3] => lens.push(n),
                _ => {
                    return Err(PyValueError::new_err(format!(
                        "{label}: expected shape (N, 3), got {:?}",
                        a.shape
                    )));
                }
            }
            arrays.push(a);
        }
        return Ok(Channels {
            arrays,
            lens,
            stacked: false,
        });
    }
    let a = sensor_array(obj, name)?;
    match *a.shape.as_slice() {
        [c, n, 3] => Ok(Channels {
            arrays: vec![a],
            lens: {
                // An empty (C, 0, 3) array can claim any C without holding any memory.
                let mut lens = Vec::new();
                lens.try_reserve_exact(c).map_err(|_| too_many(name, c))?;
                lens.resize(c, n);
                lens
            },
            stacked: true,
        }),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected shape (C, N, 3) or a list of (N, 3) arrays, got shape {:?}",
            a.shape
        ))),
    }
}

/// Views of one base array that a list of channels borrows whatever their length; past them
/// views of at most [`COPIED_VIEW_VALUES`] values are copied ([`sensor_array_copied`]).
const BORROWED_VIEWS: usize = 16;

/// Values (3 per sample) of the longest view of a shared base that is copied: 2¹⁷, 1 MiB of
/// float64.
const COPIED_VIEW_VALUES: usize = 1 << 17;

/// Bytes `run_many` holds per channel whatever its length (its filter, specification,
/// steps and result), measured at about 1.2 KB.
const BYTES_PER_CHANNEL: usize = 1280;

fn too_many(name: &str, channels: usize) -> PyErr {
    PyMemoryError::new_err(format!(
        "{name}: {channels} channels need about {BYTES_PER_CHANNEL} bytes each whatever their length, more memory than can be allocated: run fewer channels per call"
    ))
}

/// Refuses, before anything is allocated per channel, a channel count whose bookkeeping
/// alone cannot be allocated (an impossible size aborted the interpreter).
fn check_channel_memory(channels: usize) -> PyResult<()> {
    let bytes = channels
        .checked_mul(BYTES_PER_CHANNEL)
        .ok_or_else(|| too_many("gyr", channels))?;
    let mut probe: Vec<u8> = Vec::new();
    probe
        .try_reserve_exact(bytes)
        .map_err(|_| too_many("gyr", channels))
}

/// `got`'s channel count and lengths against `want`'s (an iterator, so that the rows of one
/// `(C, N)` array are compared without a vector of `C` lengths: a `(C, 0)` array costs NumPy
/// nothing for any `C`).
fn check_lens(
    name: &str,
    got: impl ExactSizeIterator<Item = usize>,
    want: &[usize],
) -> PyResult<()> {
    if got.len() != want.len() {
        return Err(PyValueError::new_err(format!(
            "{name}: has {} channels but gyr has {}",
            got.len(),
            want.len()
        )));
    }
    for (c, (g, &w)) in got.zip(want).enumerate() {
        if g != w {
            return Err(PyValueError::new_err(format!(
                "{name}[{c}]: has {g} samples but gyr[{c}] has {w}"
            )));
        }
    }
    Ok(())
}

/// Each channel's steps: one [`Steps`] per channel, or the rows of one `(C, N)` array of
/// steps or times, borrowed from NumPy where it is float64 in C order (not copied per channel).
enum ChannelSteps<'py> {
    Each(Vec<Steps>),
    Rows {
        array: crate::arrays::FloatArray<'py>,
        n: usize,
        times: bool,
    },
}

impl ChannelSteps<'_> {
    /// Channel `c`'s steps.
    fn channel(&self, c: usize) -> StepsRef<'_> {
        match self {
            Self::Each(steps) => steps[c].borrowed(),
            Self::Rows { array, n, times } => {
                let row = &array.as_slice()[c * n..(c + 1) * n];
                if *times {
                    StepsRef::Times(row)
                } else {
                    StepsRef::PerSample(row)
                }
            }
        }
    }
}

/// Per-channel steps from `dt` (a number; a `(C, N)` array; a list of `(N_i,)` arrays) or `t`
/// (the same shapes, sample times).
fn channel_steps<'py>(
    dt: Option<&Bound<'py, PyAny>>,
    t: Option<&Bound<'py, PyAny>>,
    lens: &[usize],
) -> PyResult<ChannelSteps<'py>> {
    let (obj, name, times) = match (dt, t) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "dt, t: give either dt or t, not both",
            ));
        }
        (None, None) => {
            return Err(PyValueError::new_err(
                "dt, t: missing the sampling: give dt (s: a number, (C, N) or a list of (N_i,)) or t (s: (C, N) or a list of (N_i,))",
            ));
        }
        (Some(dt), None) => (dt, "dt", false),
        (None, Some(t)) => (t, "t", true),
    };
    let make = |v: Vec<f64>| {
        if times {
            Steps::Times(v)
        } else {
            Steps::PerSample(v)
        }
    };
    if !times && obj.cast::<numpy::PyUntypedArray>().is_err() && !is_sequence(obj) {
        const EXPECTED: &str =
            "dt: expected a number (the step, s), a (C, N) array or a list of (N_i,) arrays";
        if is_bool(obj) {
            return Err(PyTypeError::new_err(format!(
                "{EXPECTED}, got a bool: booleans are not numbers here"
            )));
        }
        let x: f64 = obj
            .extract()
            .map_err(|_| PyTypeError::new_err(format!("{EXPECTED}, got {}", type_name(obj))))?;
        let x = positive(x, "dt")?;
        return Ok(ChannelSteps::Each(vec![Steps::Fixed(x); lens.len()]));
    }
    if is_sequence(obj) {
        let mut out = Vec::new();
        let mut got = Vec::new();
        for (c, item) in obj.try_iter()?.enumerate() {
            let v = vector(&item?, &format!("{name}[{c}]"))?;
            got.push(v.len());
            out.push(make(v));
        }
        check_lens(name, got.into_iter(), lens)?;
        return Ok(ChannelSteps::Each(out));
    }
    let a = float_array(obj, name)?;
    let shape = a.shape.clone();
    match *shape.as_slice() {
        [c, n] => {
            check_lens(name, core::iter::repeat_n(n, c), lens)?;
            Ok(ChannelSteps::Rows { array: a, n, times })
        }
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected shape (C, N) or a list of (N_i,) arrays, got shape {shape:?}"
        ))),
    }
}

/// The filter of each of `count` channels: `params` for all, each overridden by its
/// `channel_params` dict.
fn channel_specs(
    py: Python<'_>,
    name: &str,
    dof: Option<DofArg>,
    params: Option<&Bound<'_, PyDict>>,
    channel_params: Option<&Bound<'_, PyList>>,
    count: usize,
) -> PyResult<Vec<FilterSpec>> {
    Ok(match channel_params {
        None => vec![spec_from(name, dof, params)?; count],
        Some(list) => {
            if list.len() != count {
                return Err(PyValueError::new_err(format!(
                    "channel_params: has {} entries but there are {count} channels",
                    list.len()
                )));
            }
            list.iter()
                .enumerate()
                .map(|(i, item)| {
                    let merged = PyDict::new(py);
                    if let Some(p) = params {
                        merged.update(p.as_mapping())?;
                    }
                    let kind = item.get_type().name().map(|n| n.to_string());
                    let item = item.cast_into::<PyDict>().map_err(|_| {
                        PyTypeError::new_err(format!(
                            "channel_params[{i}]: expected a dict of parameters, got {}",
                            kind.unwrap_or_default()
                        ))
                    })?;
                    merged.update(item.as_mapping())?;
                    // The channel named in the error, as the same type (ValueError, TypeError).
                    spec_from(name, dof, Some(&merged)).map_err(|e| {
                        PyErr::from_type(
                            e.get_type(py),
                            format!("channel_params[{i}]: {}", e.value(py)),
                        )
                    })
                })
                .collect::<PyResult<_>>()?
        }
    })
}

/// `series=False`: every channel's final orientation, bias and rejection counts.
fn final_states<'py>(
    py: Python<'py>,
    specs: &[FilterSpec],
    sources: &[Inputs<'_>],
    prec: Precision,
    count: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let states = py
        .detach(|| run_final_states(specs, sources, prec))
        .map_err(|e| {
            PyValueError::new_err(format!(
                "channel_params[{}]: not the same filter",
                e.channel
            ))
        })?;
    let q: Vec<f64> = states
        .iter()
        .flat_map(|s| [s.quat.w, s.quat.x, s.quat.y, s.quat.z])
        .collect();
    let b: Vec<f64> = states
        .iter()
        .flat_map(|s| [s.bias.x, s.bias.y, s.bias.z])
        .collect();
    let s: Vec<f64> = states
        .iter()
        .flat_map(|s| [s.gyro_scale.x, s.gyro_scale.y, s.gyro_scale.z])
        .collect();
    let out = PyDict::new(py);
    out.set_item("quat", PyArray1::from_vec(py, q).reshape([count, 4])?)?;
    out.set_item("bias", PyArray1::from_vec(py, b).reshape([count, 3])?)?;
    out.set_item("gyro_scale", PyArray1::from_vec(py, s).reshape([count, 3])?)?;
    let dicts = RejectionDicts::new(py)?;
    let rej = PyList::empty(py);
    for s in &states {
        rej.append(dicts.dict(&s.rejections)?)?;
    }
    out.set_item("rejections", rej)?;
    Ok(out.into_any())
}

/// Runs many channels of one registered filter through the SIMD batch engine (`f32x8` or
/// `f64x4` lanes, two vectors interleaved for the small filters, chunks spread over all cores
/// with the GIL released). Each channel's result equals running it alone through
/// `Filter(name, ...)` bit for bit. Before any filter runs, four channels (the first, the
/// last and two between) are checked as `Filter.update_batch` checks a stream: a
/// `UserWarning` names the channel where most steps would be skipped or the readings look
/// like °/s, g or nT.
///
/// gyr, acc, mag: `(C, N, 3)` arrays, or lists of `(N_i, 3)` arrays (channels of different
/// lengths), float32 or float64 (read as they are, without a widening copy); `mag=None` for
/// 6D data. `dt`: a number (s), a `(C, N)` array or a list of `(N_i,)` arrays; or `t`: sample
/// times in the same shapes. `params` apply to every channel; `channel_params`, a list of C
/// dicts, override them per channel (same filter, any parameters: channels of equal
/// parameters share SIMD chunks).
///
/// `precision`: `"f32"` by default (`f32x8` lanes: twice the channels per vector of
/// `"f64"`, about 1e-6 relative rounding), unlike `Filter`, whose default is `"f64"`; each
/// channel equals a `Filter` of the same precision bit for bit.
///
/// With `series=True` returns, for `(C, N, 3)` input, a dict of float64 arrays `quat`
/// `(C, N, 4)`, `bias` `(C, N, 3)` (if `bias`), `covariance` `(C, N, 3, 3)` (if `covariance`
/// and the filter has one), `flags` `(C, N)` uint8 (if `flags`) and `rejections` (a list of
/// per-channel count dicts); for list input a list of such dicts per channel. The arrays are
/// allocated once and written by the engine as it runs; series not asked for are neither
/// computed nor allocated. `dtype="float32"` (or `numpy.float32`) makes the series float32:
/// half the memory, and writing them is most of a series run's cost beyond the filters
/// (`docs/performance.md`); with `precision="f32"` their values are the float64 ones exactly,
/// with `"f64"` rounded. With `series=False` only the final state: `{"quat": (C, 4),
/// "bias": (C, 3), "gyro_scale": (C, 3), "rejections": [...]}` (`gyro_scale`: each channel's
/// estimated scale error per sensor axis, a fraction, zeros for filters without one).
///
/// `out`: for `(C, N, 3)` input, a dict of arrays to write the series into instead of new
/// ones (the keys and shapes of the result, one float type, C-contiguous and writeable; their
/// float type is the series' `dtype`): a caller that runs fleet after fleet of one shape
/// reuses its memory, where new arrays cost the system zeroing their pages. Returns a dict
/// holding those same arrays.
#[pyfunction]
#[pyo3(signature = (name, gyr, acc, mag=None, dt=None, *, t=None, dof=None, precision="f32", channel_params=None, series=true, bias=true, covariance=false, flags=true, dtype=None, out=None, **params))]
#[allow(clippy::too_many_arguments)]
pub fn run_many<'py>(
    py: Python<'py>,
    name: &str,
    gyr: &Bound<'py, PyAny>,
    acc: &Bound<'py, PyAny>,
    mag: Option<&Bound<'py, PyAny>>,
    dt: Option<&Bound<'py, PyAny>>,
    t: Option<&Bound<'py, PyAny>>,
    dof: Option<DofArg>,
    precision: &str,
    channel_params: Option<&Bound<'py, PyList>>,
    series: bool,
    bias: bool,
    covariance: bool,
    flags: bool,
    dtype: Option<&Bound<'py, PyAny>>,
    out: Option<&Bound<'py, PyAny>>,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let prec = crate::filter::precision(precision)?;
    let out = match out.filter(|o| !o.is_none()) {
        Some(o) => Some(o.cast::<PyDict>().map_err(|_| {
            PyTypeError::new_err(format!(
                "out: expected a dict of arrays (keys quat, bias, covariance, flags), got {}",
                type_name(o)
            ))
        })?),
        None => None,
    };
    let single = match out {
        Some(o) => out_dtype(py, o, dtype)?,
        None => series_dtype(py, dtype)?,
    };
    let g = channels(gyr, "gyr")?;
    let a = channels(acc, "acc")?;
    check_lens("acc", a.lens.iter().copied(), &g.lens)?;
    if g.stacked != a.stacked {
        return Err(PyTypeError::new_err(
            "acc: give gyr, acc and mag in the same form: all (C, N, 3) arrays or all lists",
        ));
    }
    let m = match mag {
        Some(m) if !m.is_none() => {
            let m = channels(m, "mag")?;
            check_lens("mag", m.lens.iter().copied(), &g.lens)?;
            Some(m)
        }
        _ => None,
    };
    let count = g.lens.len();
    check_channel_memory(count)?;
    let steps = channel_steps(dt, t, &g.lens)?;
    let specs = channel_specs(py, name, dof, params, channel_params, count)?;
    let sources: Vec<Inputs<'_>> = (0..count)
        .map(|c| Inputs {
            gyr: g.channel(c),
            acc: a.channel(c),
            mag: m.as_ref().map(|m| m.channel(c)),
            steps: steps.channel(c),
            len: g.lens[c],
        })
        .collect();
    warn_of_channels(py, &specs, &sources)?;
    if !series {
        if out.is_some() {
            return Err(PyValueError::new_err(
                "out: series=False returns only the final state: give out with series=True",
            ));
        }
        return final_states(py, &specs, &sources, prec, count);
    }
    if let Some(out) = out {
        if !g.stacked {
            return Err(PyTypeError::new_err(
                "out: only for (C, N, 3) input arrays, not lists of channels",
            ));
        }
        // `t` or `dt` as a (C, N) float64 array is read in place, as the sensors are.
        let inputs = [
            Some(gyr),
            Some(acc),
            mag.filter(|m| !m.is_none()),
            dt.filter(|x| !x.is_none()),
            t.filter(|x| !x.is_none()),
        ];
        check_out_memory(py, out, &inputs)?;
    }
    let has_cov = specs
        .first()
        .is_some_and(|s| s.build::<f64>().attitude_covariance().is_some());
    let columns = Columns {
        bias,
        covariance: covariance && has_cov,
        flags,
    };
    let run = Series {
        specs: &specs,
        sources: &sources,
        lens: &g.lens,
        stacked: g.stacked,
        prec,
        columns,
    };
    if single {
        run.into_arrays::<f32>(py, out)
    } else {
        run.into_arrays::<f64>(py, out)
    }
}

/// Warnings about the input of the channels the unit check reads
/// ([`checked_channels`](crate::unit_warnings::checked_channels)): most steps skipped (as
/// `Filter.update_batch` says it; the first channel that shows it), then readings in other
/// units; before any filter runs.
fn warn_of_channels(py: Python<'_>, specs: &[FilterSpec], sources: &[Inputs<'_>]) -> PyResult<()> {
    for c in crate::unit_warnings::checked_channels(sources.len()) {
        let max_dt = specs[c].screen_limits().max_dt;
        let call = format!("run_many: channel {c}");
        let s = &sources[c];
        // One channel's warning says it for the fleet.
        if crate::unit_warnings::warn_if_most_steps_skipped(py, &call, s.steps, s.len, max_dt)? {
            break;
        }
    }
    let findings = py.detach(|| crate::unit_warnings::channel_findings(sources, specs));
    for (c, f) in &findings {
        let call = format!("run_many: channel {c}");
        crate::unit_warnings::warn_findings(py, &call, [f])?;
    }
    Ok(())
}

/// Refuses `out` arrays that may share memory with an input or with each other
/// (`numpy.may_share_memory`: NumPy's borrow tracking sees only views of one base object,
/// not two buffers over the same memory).
fn check_out_memory(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    inputs: &[Option<&Bound<'_, PyAny>>],
) -> PyResult<()> {
    let shares = py.import("numpy")?.getattr("may_share_memory")?;
    let items: Vec<(String, Bound<'_, PyAny>)> =
        out.iter().map(|(k, v)| (k.to_string(), v)).collect();
    for (i, (key, array)) in items.iter().enumerate() {
        let named_inputs = ["gyr", "acc", "mag", "dt", "t"].into_iter().zip(inputs);
        for (name, input) in named_inputs.filter_map(|(n, x)| x.map(|x| (n, x))) {
            if shares.call1((array, input))?.is_truthy()? {
                return Err(PyValueError::new_err(format!(
                    "out[{key:?}]: shares memory with {name}: give arrays of their own"
                )));
            }
        }
        for (other, array2) in &items[i + 1..] {
            if shares.call1((array, array2))?.is_truthy()? {
                return Err(PyValueError::new_err(format!(
                    "out[{key:?}]: shares memory with out[{other:?}]: give arrays of their own"
                )));
            }
        }
    }
    Ok(())
}

/// `out`'s float type (true for float32): that of its `"quat"` array, which `dtype`, if
/// given, must name.
fn out_dtype(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    dtype: Option<&Bound<'_, PyAny>>,
) -> PyResult<bool> {
    let quat = out.get_item("quat")?.ok_or_else(|| {
        PyValueError::new_err("out: missing \"quat\": a (C, N, 4) float32 or float64 array")
    })?;
    let single = if quat.cast::<PyArrayDyn<f32>>().is_ok() {
        true
    } else if quat.cast::<PyArrayDyn<f64>>().is_ok() {
        false
    } else {
        return Err(PyTypeError::new_err(format!(
            "out[\"quat\"]: expected a float32 or float64 array, got {}",
            crate::arrays::dtype_name(&quat)
        )));
    };
    if dtype.is_some_and(|d| !d.is_none()) && series_dtype(py, dtype)? != single {
        return Err(PyValueError::new_err(
            "dtype: differs from out's arrays; leave dtype out to write in theirs",
        ));
    }
    Ok(single)
}

/// `dtype`: true for float32 series, false for float64 (the default, `None`).
fn series_dtype(py: Python<'_>, dtype: Option<&Bound<'_, PyAny>>) -> PyResult<bool> {
    let Some(obj) = dtype.filter(|d| !d.is_none()) else {
        return Ok(false);
    };
    let name: Option<String> = py
        .import("numpy")
        .and_then(|np| {
            np.getattr("dtype")?
                .call1((obj,))?
                .getattr("name")?
                .extract()
        })
        .ok();
    match name.as_deref() {
        Some("float32") => Ok(true),
        Some("float64") => Ok(false),
        _ => Err(PyTypeError::new_err(format!(
            "dtype: expected \"float32\" or \"float64\" (or the numpy types), got {}",
            obj.repr()
                .map_or_else(|_| type_name(obj), |r| r.to_string())
        ))),
    }
}

/// A series run's inputs, written into NumPy arrays of one float type.
struct Series<'a, 'b> {
    specs: &'a [FilterSpec],
    sources: &'a [Inputs<'b>],
    lens: &'a [usize],
    stacked: bool,
    prec: Precision,
    columns: Columns,
}

impl Series<'_, '_> {
    /// The series in new arrays, or in the caller's `out` (stacked input only).
    fn into_arrays<'py, E: SeriesFloat>(
        self,
        py: Python<'py>,
        out: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (count, columns) = (self.lens.len(), self.columns);
        // The outputs: one set of arrays for stacked input (each channel a contiguous part of
        // it), one per channel for lists.
        let shapes: Vec<Vec<usize>> = if self.stacked {
            vec![vec![count, self.lens.first().copied().unwrap_or(0)]]
        } else {
            self.lens.iter().map(|&n| vec![n]).collect()
        };
        let outputs: Vec<SeriesArrays<'py, E>> = match out {
            Some(out) => vec![SeriesArrays::given(out, &shapes[0], columns)?],
            None => shapes
                .iter()
                .map(|lead| SeriesArrays::zeros(py, lead, columns))
                .collect(),
        };
        let mut views: Vec<SeriesViews<'_, 'py, E>> = outputs
            .iter()
            .map(SeriesArrays::views)
            .collect::<PyResult<_>>()?;
        let per_array = if self.stacked { count } else { 1 };
        let mut sinks: Vec<ArraySink<'_, E>> = Vec::with_capacity(count);
        for v in &mut views {
            sinks.extend(v.split(per_array));
        }
        py.detach(|| run_grouped(self.specs, self.sources, &mut sinks, self.prec, columns));
        let rejections: Vec<RejectionTotals> = sinks.iter().map(|s| s.rejections).collect();
        drop(sinks);
        drop(views);
        let dicts = outputs
            .into_iter()
            .map(|o| o.into_dict(py))
            .collect::<PyResult<Vec<_>>>()?;
        if self.stacked {
            let out = dicts.into_iter().next().unwrap_or_else(|| PyDict::new(py));
            let rej = PyList::empty(py);
            let counts = RejectionDicts::new(py)?;
            for r in &rejections {
                rej.append(counts.dict(r)?)?;
            }
            out.set_item("rejections", rej)?;
            Ok(out.into_any())
        } else {
            let list = PyList::empty(py);
            let counts = RejectionDicts::new(py)?;
            for (d, r) in dicts.into_iter().zip(&rejections) {
                d.set_item("rejections", counts.dict(r)?)?;
                list.append(d)?;
            }
            Ok(list.into_any())
        }
    }
}

/// Channels grouped by equal spec, each group through the batch engine, every channel's
/// estimates into its own sink (a channel's result does not depend on its chunk mates).
fn run_grouped<E: SeriesFloat>(
    specs: &[FilterSpec],
    sources: &[Inputs<'_>],
    sinks: &mut [ArraySink<'_, E>],
    prec: Precision,
    columns: Columns,
) {
    let mut groups: Vec<(&FilterSpec, Vec<usize>)> = Vec::new();
    for (c, s) in specs.iter().enumerate() {
        match groups.iter_mut().find(|(g, _)| *g == s) {
            Some((_, members)) => members.push(c),
            None => groups.push((s, vec![c])),
        }
    }
    if groups.len() == 1 {
        run_into_sinks(&specs[0], prec, sources, sinks, columns);
        return;
    }
    for (spec, members) in groups {
        let srcs: Vec<&Inputs<'_>> = members.iter().map(|&c| &sources[c]).collect();
        let mut group: Vec<ArraySink<'_, E>> = members
            .iter()
            .map(|&c| std::mem::take(&mut sinks[c]))
            .collect();
        run_into_sinks(spec, prec, &srcs, &mut group, columns);
        for (c, s) in members.into_iter().zip(group) {
            sinks[c] = s;
        }
    }
}
