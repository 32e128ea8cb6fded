//! Many channels through the SIMD batch engine (`rootfuse_batch`), on all cores.

use crate::arrays::{FloatArray, Steps, float_array, positive, vector};
use crate::filter::{Inputs, rejections_dict, spec_from};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use rootfuse_attitude::Lane;
use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
use rootfuse_batch::{Batch, ChannelOutput, Columns, Precision, RejectionTotals, run_sources_with};
use rootfuse_lane::wide::{f32x8, f64x4};

/// Channels as given: one `(C, N, 3)` array, or a list of `(N_i, 3)` arrays.
struct Channels<'py> {
    /// One array per channel when a list was given; one array of all channels otherwise.
    arrays: Vec<FloatArray<'py>>,
    /// Samples of each channel.
    lens: Vec<usize>,
    /// True when the input was a `(C, N, 3)` array.
    stacked: bool,
}

impl Channels<'_> {
    fn channel(&self, c: usize) -> &[f64] {
        if self.stacked {
            let n = self.lens.first().copied().unwrap_or(0);
            &self.arrays[0].as_slice()[c * n * 3..(c + 1) * n * 3]
        } else {
            self.arrays[c].as_slice()
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
        for (c, item) in obj.try_iter()?.enumerate() {
            let item = item?;
            let label = format!("{name}[{c}]");
            let a = float_array(&item, &label)?;
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
    let a = float_array(obj, name)?;
    match *a.shape.as_slice() {
        [c, n, 3] => Ok(Channels {
            arrays: vec![a],
            lens: vec![n; c],
            stacked: true,
        }),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected shape (C, N, 3) or a list of (N, 3) arrays, got shape {:?}",
            a.shape
        ))),
    }
}

fn check_lens(name: &str, got: &[usize], want: &[usize]) -> PyResult<()> {
    if got.len() != want.len() {
        return Err(PyValueError::new_err(format!(
            "{name}: has {} channels but gyr has {}",
            got.len(),
            want.len()
        )));
    }
    for (c, (g, w)) in got.iter().zip(want).enumerate() {
        if g != w {
            return Err(PyValueError::new_err(format!(
                "{name}[{c}]: has {g} samples but gyr[{c}] has {w}"
            )));
        }
    }
    Ok(())
}

/// Per-channel steps from `dt` (a number; a `(C, N)` array; a list of `(N_i,)` arrays) or `t`
/// (the same shapes, sample times).
fn channel_steps(
    dt: Option<&Bound<'_, PyAny>>,
    t: Option<&Bound<'_, PyAny>>,
    lens: &[usize],
) -> PyResult<Vec<Steps>> {
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
        let x: f64 = obj.extract().map_err(|_| {
            PyTypeError::new_err("dt: expected a number, a (C, N) array or a list of (N_i,) arrays")
        })?;
        let x = positive(x, "dt")?;
        return Ok(vec![Steps::Fixed(x); lens.len()]);
    }
    if is_sequence(obj) {
        let mut out = Vec::new();
        let mut got = Vec::new();
        for (c, item) in obj.try_iter()?.enumerate() {
            let v = vector(&item?, &format!("{name}[{c}]"))?;
            got.push(v.len());
            out.push(make(v));
        }
        check_lens(name, &got, lens)?;
        return Ok(out);
    }
    let a = float_array(obj, name)?;
    let shape = a.shape.clone();
    match *shape.as_slice() {
        [c, n] => {
            check_lens(name, &vec![n; c], lens)?;
            let data = a.as_slice();
            Ok((0..c)
                .map(|k| make(data[k * n..(k + 1) * n].to_vec()))
                .collect())
        }
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected shape (C, N) or a list of (N_i,) arrays, got shape {shape:?}"
        ))),
    }
}

/// Final states only: the batch with per-channel specs, fed all channels.
struct FinalStates<'a> {
    specs: &'a [FilterSpec],
    sources: &'a [Inputs<'a>],
}

impl<L: Lane> FilterVisitor<L> for FinalStates<'_> {
    type Output = Result<Vec<(Vec<f64>, RejectionTotals)>, usize>;
    fn visit<F: RegisteredFilter<L>>(self, _: &FilterSpec) -> Self::Output {
        let mut batch = Batch::<L, F>::with_channel_specs(self.specs).map_err(|e| e.channel)?;
        batch.run_channels(self.sources);
        Ok((0..self.specs.len())
            .map(|c| {
                let (q, b) = (batch.quat(c), batch.bias(c));
                (vec![q.w, q.x, q.y, q.z, b.x, b.y, b.z], batch.rejections(c))
            })
            .collect())
    }
}

/// Runs many channels of one registered filter through the SIMD batch engine (`f32x8` or
/// `f64x4` lanes, chunks spread over all cores with the GIL released). Each channel's result
/// equals running it alone through `Filter(name, ...)` bit for bit.
///
/// gyr, acc, mag: `(C, N, 3)` arrays, or lists of `(N_i, 3)` arrays (channels of different
/// lengths); `mag=None` for 6D data. `dt`: a number (s), a `(C, N)` array or a list of `(N_i,)`
/// arrays; or `t`: sample times in the same shapes. `params` apply to every channel;
/// `channel_params`, a list of C dicts, override them per channel (same filter, any
/// parameters: channels of equal parameters share SIMD chunks).
///
/// With `series=True` returns, for `(C, N, 3)` input, a dict of float64 arrays `quat`
/// `(C, N, 4)`, `bias` `(C, N, 3)` (if `bias`), `covariance` `(C, N, 3, 3)` (if `covariance`
/// and the filter has one), `flags` `(C, N)` uint8 (if `flags`) and `rejections` (a list of
/// per-channel count dicts); for list input a list of such dicts per channel. With
/// `series=False` only the final state: `{"quat": (C, 4), "bias": (C, 3), "rejections": [...]}`.
#[pyfunction]
#[pyo3(signature = (name, gyr, acc, mag=None, dt=None, *, t=None, dof=None, precision="f32", channel_params=None, series=true, bias=true, covariance=false, flags=true, **params))]
#[allow(clippy::too_many_arguments)]
pub fn run_many<'py>(
    py: Python<'py>,
    name: &str,
    gyr: &Bound<'py, PyAny>,
    acc: &Bound<'py, PyAny>,
    mag: Option<&Bound<'py, PyAny>>,
    dt: Option<&Bound<'py, PyAny>>,
    t: Option<&Bound<'py, PyAny>>,
    dof: Option<u8>,
    precision: &str,
    channel_params: Option<&Bound<'py, PyList>>,
    series: bool,
    bias: bool,
    covariance: bool,
    flags: bool,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let prec = crate::filter::precision(precision)?;
    let g = channels(gyr, "gyr")?;
    let a = channels(acc, "acc")?;
    check_lens("acc", &a.lens, &g.lens)?;
    if g.stacked != a.stacked {
        return Err(PyTypeError::new_err(
            "acc: give gyr, acc and mag in the same form: all (C, N, 3) arrays or all lists",
        ));
    }
    let m = match mag {
        Some(m) if !m.is_none() => {
            let m = channels(m, "mag")?;
            check_lens("mag", &m.lens, &g.lens)?;
            Some(m)
        }
        _ => None,
    };
    let steps = channel_steps(dt, t, &g.lens)?;
    let count = g.lens.len();
    let specs: Vec<FilterSpec> = match channel_params {
        None => vec![spec_from(name, dof, params)?; count],
        Some(list) => {
            if list.len() != count {
                return Err(PyValueError::new_err(format!(
                    "channel_params: has {} entries but there are {count} channels",
                    list.len()
                )));
            }
            list.iter()
                .map(|item| {
                    let merged = PyDict::new(py);
                    if let Some(p) = params {
                        merged.update(p.as_mapping())?;
                    }
                    let item = item.cast_into::<PyDict>().map_err(|_| {
                        PyTypeError::new_err("channel_params: expected a list of dicts")
                    })?;
                    merged.update(item.as_mapping())?;
                    spec_from(name, dof, Some(&merged))
                })
                .collect::<PyResult<_>>()?
        }
    };
    let sources: Vec<Inputs<'_>> = (0..count)
        .map(|c| Inputs {
            gyr: g.channel(c),
            acc: a.channel(c),
            mag: m.as_ref().map(|m| m.channel(c)),
            steps: &steps[c],
            len: g.lens[c],
        })
        .collect();
    if !series {
        let visitor = FinalStates {
            specs: &specs,
            sources: &sources,
        };
        let result = py.detach(|| match prec {
            Precision::F32 => specs.first().map(|s| s.visit::<f32x8, _>(visitor)),
            Precision::F64 => specs.first().map(|s| s.visit::<f64x4, _>(visitor)),
        });
        let states = result.unwrap_or(Ok(Vec::new())).map_err(|c| {
            PyValueError::new_err(format!("channel_params[{c}]: not the same filter"))
        })?;
        let q: Vec<f64> = states.iter().flat_map(|(s, _)| s[..4].to_vec()).collect();
        let b: Vec<f64> = states.iter().flat_map(|(s, _)| s[4..].to_vec()).collect();
        let out = PyDict::new(py);
        out.set_item("quat", PyArray1::from_vec(py, q).reshape([count, 4])?)?;
        out.set_item("bias", PyArray1::from_vec(py, b).reshape([count, 3])?)?;
        let rej = PyList::empty(py);
        for (_, r) in &states {
            rej.append(rejections_dict(py, r)?)?;
        }
        out.set_item("rejections", rej)?;
        return Ok(out.into_any());
    }
    let columns = Columns {
        bias,
        covariance,
        flags,
    };
    let outputs = py.detach(|| run_grouped(&specs, &sources, prec, columns));
    if g.stacked {
        stacked_output(
            py,
            &outputs,
            count,
            g.lens.first().copied().unwrap_or(0),
            columns,
        )
    } else {
        let list = PyList::empty(py);
        for o in &outputs {
            list.append(
                stacked_output(py, std::slice::from_ref(o), 1, o.quat.len(), columns)?
                    .cast_into::<PyDict>()
                    .map(|d| squeeze(py, d))??,
            )?;
        }
        Ok(list.into_any())
    }
}

/// Drops the leading channel axis of a one-channel result.
fn squeeze<'py>(py: Python<'py>, d: Bound<'py, PyDict>) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (k, v) in d.iter() {
        out.set_item(k, v.get_item(0)?)?;
    }
    Ok(out)
}

/// Channels grouped by equal spec, each group through `run_sources_with`, outputs in channel
/// order (a channel's result does not depend on its chunk mates).
fn run_grouped(
    specs: &[FilterSpec],
    sources: &[Inputs<'_>],
    prec: Precision,
    columns: Columns,
) -> Vec<ChannelOutput> {
    let mut groups: Vec<(&FilterSpec, Vec<usize>)> = Vec::new();
    for (c, s) in specs.iter().enumerate() {
        match groups.iter_mut().find(|(g, _)| *g == s) {
            Some((_, members)) => members.push(c),
            None => groups.push((s, vec![c])),
        }
    }
    let mut out = vec![ChannelOutput::default(); specs.len()];
    for (spec, members) in groups {
        let srcs: Vec<&Inputs<'_>> = members.iter().map(|&c| &sources[c]).collect();
        let results = match prec {
            Precision::F32 => run_sources_with::<f32x8, _>(spec, &srcs, columns),
            Precision::F64 => run_sources_with::<f64x4, _>(spec, &srcs, columns),
        };
        for (c, r) in members.into_iter().zip(results) {
            out[c] = r;
        }
    }
    out
}

/// `(C, N, ...)` arrays of equal-length channel outputs.
fn stacked_output<'py>(
    py: Python<'py>,
    outputs: &[ChannelOutput],
    count: usize,
    n: usize,
    columns: Columns,
) -> PyResult<Bound<'py, PyAny>> {
    let out = PyDict::new(py);
    let mut q = Vec::with_capacity(count * n * 4);
    for o in outputs {
        q.extend(o.quat.iter().flat_map(|q| [q.w, q.x, q.y, q.z]));
    }
    out.set_item("quat", PyArray1::from_vec(py, q).reshape([count, n, 4])?)?;
    if columns.bias {
        let mut b = Vec::with_capacity(count * n * 3);
        for o in outputs {
            b.extend(o.bias.iter().flat_map(|b| [b.x, b.y, b.z]));
        }
        out.set_item("bias", PyArray1::from_vec(py, b).reshape([count, n, 3])?)?;
    }
    if columns.covariance && outputs.iter().all(|o| o.covariance.len() == o.quat.len()) && n > 0 {
        let mut p = Vec::with_capacity(count * n * 9);
        for o in outputs {
            p.extend(
                o.covariance
                    .iter()
                    .flat_map(|u| [u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5]]),
            );
        }
        out.set_item(
            "covariance",
            PyArray1::from_vec(py, p).reshape([count, n, 3, 3])?,
        )?;
    }
    if columns.flags {
        let mut f = Vec::with_capacity(count * n);
        for o in outputs {
            f.extend_from_slice(&o.flags);
        }
        out.set_item("flags", PyArray1::from_vec(py, f).reshape([count, n])?)?;
    }
    let rej = PyList::empty(py);
    for o in outputs {
        rej.append(rejections_dict(py, &o.rejections)?)?;
    }
    out.set_item("rejections", rej)?;
    Ok(out.into_any())
}
