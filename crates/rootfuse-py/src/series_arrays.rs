//! The NumPy arrays `run_many` writes its series into: allocated once (or the caller's
//! `out`), split into one [`ArraySink`] per channel that the batch engine fills as it runs.

use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rootfuse_attitude::Lane;
use rootfuse_batch::{
    Columns, Estimate, EstimateSink, MAX_LANES, RejectionTotals, push_quat_per_lane,
};

/// The float types series are written in: the engine's f64 estimates converted on the way
/// in (exactly, for `f32` lanes' values into `f32`).
pub(crate) trait SeriesFloat: numpy::Element + Copy {
    fn of(x: f64) -> Self;
}

impl SeriesFloat for f64 {
    #[inline]
    fn of(x: f64) -> Self {
        x
    }
}

impl SeriesFloat for f32 {
    #[inline]
    fn of(x: f64) -> Self {
        x as f32
    }
}

/// The series arrays of one output dict, allocated once with `zeros` (numpy maps zeroed
/// pages lazily, so the engine's write is the only touch), shapes `lead + [4]` etc.
pub(crate) struct SeriesArrays<'py, E: SeriesFloat> {
    quat: Bound<'py, PyArrayDyn<E>>,
    bias: Option<Bound<'py, PyArrayDyn<E>>>,
    covariance: Option<Bound<'py, PyArrayDyn<E>>>,
    flags: Option<Bound<'py, PyArrayDyn<u8>>>,
}

impl<'py, E: SeriesFloat> SeriesArrays<'py, E> {
    pub(crate) fn zeros(py: Python<'py>, lead: &[usize], columns: Columns) -> Self {
        let shape = |tail: &[usize]| -> Vec<usize> { lead.iter().chain(tail).copied().collect() };
        Self {
            quat: PyArrayDyn::zeros(py, shape(&[4]), false),
            bias: columns
                .bias
                .then(|| PyArrayDyn::zeros(py, shape(&[3]), false)),
            covariance: columns
                .covariance
                .then(|| PyArrayDyn::zeros(py, shape(&[3, 3]), false)),
            flags: columns
                .flags
                .then(|| PyArrayDyn::zeros(py, shape(&[]), false)),
        }
    }

    /// The caller's arrays of `out` (see `run_many`), checked against the shapes `lead + [4]`
    /// etc. of the series asked for: nothing is written unless every one fits.
    pub(crate) fn given(
        out: &Bound<'py, PyDict>,
        lead: &[usize],
        columns: Columns,
    ) -> PyResult<Self> {
        for key in out.keys() {
            let key: String = key.extract().unwrap_or_default();
            let computed = match key.as_str() {
                "quat" => true,
                "bias" => columns.bias,
                "covariance" => columns.covariance,
                "flags" => columns.flags,
                _ => {
                    return Err(PyValueError::new_err(format!(
                        "out: unknown key {key:?} (expected quat, bias, covariance, flags)"
                    )));
                }
            };
            // An array that is not written would keep an earlier fleet's values unnoticed.
            if !computed {
                return Err(PyValueError::new_err(format!(
                    "out: has {key:?}, a series this call does not compute ({key}=False, or a filter without it): remove the key"
                )));
            }
        }
        fn array<'py, T: numpy::Element>(
            out: &Bound<'py, PyDict>,
            key: &str,
            shape: Vec<usize>,
            what: &str,
        ) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
            let item = out.get_item(key)?.ok_or_else(|| {
                PyValueError::new_err(format!(
                    "out: missing {key:?}: a {shape:?} {what} array (or pass {key}=False)"
                ))
            })?;
            let a = item.cast::<PyArrayDyn<T>>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "out[{key:?}]: expected a {what} array, got {}",
                    crate::arrays::dtype_name(&item)
                ))
            })?;
            if a.shape() != shape.as_slice() || !a.is_c_contiguous() {
                return Err(PyValueError::new_err(format!(
                    "out[{key:?}]: expected a C-contiguous array of shape {shape:?}, got shape {:?}{}",
                    a.shape(),
                    if a.is_c_contiguous() {
                        ""
                    } else {
                        ", not C-contiguous"
                    }
                )));
            }
            // A slice of `T` must be aligned (NumPy allows unaligned arrays, from a buffer).
            if !(a.data() as usize).is_multiple_of(std::mem::align_of::<T>()) {
                return Err(PyValueError::new_err(format!(
                    "out[{key:?}]: the array's memory is not aligned for {what}: give an array NumPy allocated (numpy.empty)"
                )));
            }
            Ok(a.clone())
        }
        let shape = |tail: &[usize]| -> Vec<usize> { lead.iter().chain(tail).copied().collect() };
        let float = if std::mem::size_of::<E>() == 4 {
            "float32"
        } else {
            "float64"
        };
        Ok(Self {
            quat: array(out, "quat", shape(&[4]), float)?,
            bias: columns
                .bias
                .then(|| array(out, "bias", shape(&[3]), float))
                .transpose()?,
            covariance: columns
                .covariance
                .then(|| array(out, "covariance", shape(&[3, 3]), float))
                .transpose()?,
            flags: columns
                .flags
                .then(|| array(out, "flags", shape(&[]), "uint8"))
                .transpose()?,
        })
    }

    pub(crate) fn views(&self) -> PyResult<SeriesViews<'_, 'py, E>> {
        // Arrays made here are not yet handed to Python; the caller's (`out`) may be read-only
        // or overlap an input, which NumPy's borrow tracking refuses.
        let busy = |e: numpy::BorrowError| {
            PyValueError::new_err(format!(
                "out: an array cannot be written ({e}): give writeable arrays that share no memory with the inputs"
            ))
        };
        Ok(SeriesViews {
            quat: self.quat.try_readwrite().map_err(busy)?,
            bias: self
                .bias
                .as_ref()
                .map(|a| a.try_readwrite())
                .transpose()
                .map_err(busy)?,
            covariance: self
                .covariance
                .as_ref()
                .map(|a| a.try_readwrite())
                .transpose()
                .map_err(busy)?,
            flags: self
                .flags
                .as_ref()
                .map(|a| a.try_readwrite())
                .transpose()
                .map_err(busy)?,
            _arrays: core::marker::PhantomData,
        })
    }

    pub(crate) fn into_dict(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        out.set_item("quat", self.quat)?;
        if let Some(b) = self.bias {
            out.set_item("bias", b)?;
        }
        if let Some(p) = self.covariance {
            out.set_item("covariance", p)?;
        }
        if let Some(f) = self.flags {
            out.set_item("flags", f)?;
        }
        Ok(out)
    }
}

/// Write access to one [`SeriesArrays`] while the engine runs.
pub(crate) struct SeriesViews<'s, 'py, E: SeriesFloat> {
    quat: numpy::PyReadwriteArrayDyn<'py, E>,
    bias: Option<numpy::PyReadwriteArrayDyn<'py, E>>,
    covariance: Option<numpy::PyReadwriteArrayDyn<'py, E>>,
    flags: Option<numpy::PyReadwriteArrayDyn<'py, u8>>,
    _arrays: core::marker::PhantomData<&'s SeriesArrays<'py, E>>,
}

impl<E: SeriesFloat> SeriesViews<'_, '_, E> {
    /// One sink per channel over `channels` equal contiguous parts of the arrays.
    pub(crate) fn split(&mut self, channels: usize) -> Vec<ArraySink<'_, E>> {
        fn parts<'a, T: numpy::Element>(
            a: Option<&'a mut numpy::PyReadwriteArrayDyn<'_, T>>,
            channels: usize,
        ) -> Vec<&'a mut [T]> {
            match a.and_then(|a| a.as_slice_mut().ok()) {
                Some(s) if channels > 0 => {
                    let per = s.len() / channels;
                    if per == 0 {
                        (0..channels).map(|_| Default::default()).collect()
                    } else {
                        s.chunks_mut(per).collect()
                    }
                }
                _ => (0..channels).map(|_| Default::default()).collect(),
            }
        }
        let quat = parts(Some(&mut self.quat), channels);
        let bias = parts(self.bias.as_mut(), channels);
        let covariance = parts(self.covariance.as_mut(), channels);
        let flags = parts(self.flags.as_mut(), channels);
        quat.into_iter()
            .zip(bias)
            .zip(covariance)
            .zip(flags)
            .map(|(((quat, bias), covariance), flags)| ArraySink {
                quat,
                bias,
                covariance,
                flags,
                rejections: RejectionTotals::default(),
            })
            .collect()
    }
}

/// One channel's part of the output arrays: sample `k` goes to rows `k` (an empty slice is
/// a series not collected).
pub(crate) struct ArraySink<'a, E> {
    quat: &'a mut [E],
    bias: &'a mut [E],
    covariance: &'a mut [E],
    flags: &'a mut [u8],
    pub(crate) rejections: RejectionTotals,
}

// Not derived: a derived `Default` would ask `E: Default` of the slices' element.
impl<E> Default for ArraySink<'_, E> {
    fn default() -> Self {
        Self {
            quat: &mut [],
            bias: &mut [],
            covariance: &mut [],
            flags: &mut [],
            rejections: RejectionTotals::default(),
        }
    }
}

impl<E: SeriesFloat> EstimateSink for ArraySink<'_, E> {
    #[inline]
    fn push(&mut self, k: usize, e: &Estimate) {
        let of = E::of;
        if let Some(q) = self.quat.get_mut(4 * k..4 * k + 4) {
            q.copy_from_slice(&[of(e.quat.w), of(e.quat.x), of(e.quat.y), of(e.quat.z)]);
        }
        if let (Some(b), Some(out)) = (e.bias, self.bias.get_mut(3 * k..3 * k + 3)) {
            out.copy_from_slice(&[of(b.x), of(b.y), of(b.z)]);
        }
        if let (Some(u), Some(out)) = (e.covariance, self.covariance.get_mut(9 * k..9 * k + 9)) {
            let u = u.map(of);
            out.copy_from_slice(&[u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5]]);
        }
        if let (Some(f), Some(out)) = (e.flags, self.flags.get_mut(k)) {
            *out = f;
        }
    }
    #[inline]
    fn push_quat(&mut self, k: usize, q: rootfuse_attitude::Quat<f64>) {
        let of = E::of;
        if let Some(out) = self.quat.get_mut(4 * k..4 * k + 4) {
            out.copy_from_slice(&[of(q.w), of(q.x), of(q.y), of(q.z)]);
        }
    }
    /// A full chunk of at least four lanes: the step's four vectors transposed in registers
    /// ([`Lane::transpose_lanes`], the rest of the block zero), so vector `i` holds lane `i`'s
    /// `[w, x, y, z, …]`, written to its sink as four values: the values of the default path,
    /// without a pass through `f64` staging arrays and a call per lane.
    #[inline]
    fn push_quat_lanes<L: Lane>(
        sinks: &mut [Self],
        active: u64,
        k: usize,
        quat: &rootfuse_attitude::Quat<L>,
    ) {
        let n = L::LANES;
        let mut block = [L::zero(); MAX_LANES];
        block[..4].copy_from_slice(&[quat.w, quat.x, quat.y, quat.z]);
        if !(4..=MAX_LANES).contains(&n) || sinks.len() != n || !L::transpose_lanes(&mut block[..n])
        {
            push_quat_per_lane(sinks, active, k, quat);
            return;
        }
        for (i, (o, v)) in sinks.iter_mut().zip(&block[..n]).enumerate() {
            if (active >> i) & 1 == 1
                && let Some(out) = o.quat.get_mut(4 * k..4 * k + 4)
            {
                let of = |j: usize| E::of(v.extract(j).into());
                out.copy_from_slice(&[of(0), of(1), of(2), of(3)]);
            }
        }
    }
    fn finish(&mut self, rejections: RejectionTotals) {
        self.rejections = rejections;
    }
}
