//! Least squares: the six recursive forms (`rootfuse_lsq::rls`) sample by sample and over
//! whole arrays, the dense weighted solvers (`rootfuse_lsq::dense`) and the stress scenarios.

use crate::arrays::{float_array, is_bool, real, real_or_none, square, symmetric, vector, whole};
use crate::filter::precision;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rootfuse_batch::Precision;
use rootfuse_lane::{Lane, Mask, Mat, Vector};
use rootfuse_lsq::dense::{self, LsqReal, Method, Options, Weights, faer};
use rootfuse_lsq::rls::{
    BiermanUd, Conventional, InformationQr, InverseQr, Joseph, Potter, RecursiveLeastSquares,
    RlsConfig,
};

/// The state sizes `Rls` is compiled for (the forms are const-generic in `n`).
pub const MAX_N: usize = 8;

/// The six form names, as `RecursiveLeastSquares::NAME`.
pub const FORMS: [&str; 6] = [
    Conventional::<f64, 1>::NAME,
    Joseph::<f64, 1>::NAME,
    Potter::<f64, 1>::NAME,
    BiermanUd::<f64, 1>::NAME,
    InverseQr::<f64, 1>::NAME,
    InformationQr::<f64, 1>::NAME,
];

/// Health of one estimator in `f64`.
struct HealthF64 {
    min_pivot: f64,
    max_pivot: f64,
    trace: f64,
    information_trace: f64,
    lost_definiteness: bool,
    accepted: u64,
    rejected_input: u64,
    rejected_numerical: u64,
    clipped: u64,
}

/// One form at one size and precision, behind an object-safe interface.
trait DynRls: Send + Sync {
    fn n(&self) -> usize;
    fn update(&mut self, h: &[f64], z: f64, weight: f64) -> bool;
    fn estimate(&self) -> Vec<f64>;
    fn covariance(&self) -> Vec<f64>;
    fn health(&self) -> HealthF64;
    fn name(&self) -> &'static str;
    /// `f` row-major `(n, n)`; `Ok(applied)`, or `Err` with why the form cannot.
    fn predict(&mut self, f: &[f64], lambda: f64) -> Result<bool, String>;
    /// `q` `(n,)`, variances added to the diagonal of `P`.
    fn time_update(&mut self, q: &[f64]) -> Result<bool, String>;
}

/// The time updates only some forms have: Potter's known transition, Bierman's process noise.
trait TimeUpdates<T: Lane, const N: usize> {
    fn predict(&mut self, _f: &Mat<T, N, N>, _lambda: T) -> Result<bool, String> {
        Err("only the potter form has a state transition (predict)".into())
    }
    fn time_update(&mut self, _q: &Vector<T, N>) -> Result<bool, String> {
        Err("only the bierman-ud form adds process noise (time_update)".into())
    }
}

impl<T: Lane, const N: usize> TimeUpdates<T, N> for Conventional<T, N> {}
impl<T: Lane, const N: usize> TimeUpdates<T, N> for Joseph<T, N> {}
impl<T: Lane, const N: usize> TimeUpdates<T, N> for InverseQr<T, N> {}
impl<T: Lane, const N: usize> TimeUpdates<T, N> for InformationQr<T, N> {}
impl<T: Lane, const N: usize> TimeUpdates<T, N> for Potter<T, N> {
    fn predict(&mut self, f: &Mat<T, N, N>, lambda: T) -> Result<bool, String> {
        Potter::predict(self, f, lambda)
            .map(|m| m.all())
            .map_err(|e| e.to_string())
    }
}
impl<T: Lane, const N: usize> TimeUpdates<T, N> for BiermanUd<T, N> {
    fn time_update(&mut self, q: &Vector<T, N>) -> Result<bool, String> {
        Ok(BiermanUd::time_update(self, q).all())
    }
}

/// A form over `T` at size `N` (the parameters name the `RecursiveLeastSquares` instance).
struct Typed<T, const N: usize, R>(R, core::marker::PhantomData<T>);

fn to_f64<T: Lane>(x: T) -> f64 {
    x.extract(0).into()
}

impl<T, const N: usize, R> DynRls for Typed<T, N, R>
where
    T: Lane<Scalar = T> + Send + Sync,
    R: RecursiveLeastSquares<T, N> + TimeUpdates<T, N> + Send + Sync,
{
    fn n(&self) -> usize {
        N
    }
    fn update(&mut self, h: &[f64], z: f64, weight: f64) -> bool {
        let h = Vector::<T, N>::from_column(core::array::from_fn(|i| T::from_f64(h[i])));
        self.0.update(&h, T::from_f64(z), T::from_f64(weight)).all()
    }
    fn estimate(&self) -> Vec<f64> {
        let x = self.0.estimate();
        (0..N).map(|i| to_f64(x[i])).collect()
    }
    fn covariance(&self) -> Vec<f64> {
        self.0
            .covariance()
            .m
            .iter()
            .flatten()
            .map(|&x| to_f64(x))
            .collect()
    }
    fn health(&self) -> HealthF64 {
        let h = self.0.health();
        HealthF64 {
            min_pivot: to_f64(h.min_pivot),
            max_pivot: to_f64(h.max_pivot),
            trace: to_f64(h.trace),
            information_trace: to_f64(h.information_trace),
            lost_definiteness: h.lost_definiteness.any(),
            accepted: h.accepted.as_ref()[0],
            rejected_input: h.rejected_input.as_ref()[0],
            rejected_numerical: h.rejected_numerical.as_ref()[0],
            clipped: h.clipped.as_ref()[0],
        }
    }
    fn name(&self) -> &'static str {
        R::NAME
    }
    fn predict(&mut self, f: &[f64], lambda: f64) -> Result<bool, String> {
        let f = Mat::<T, N, N>::from_fn(|r, c| T::from_f64(f[r * N + c]));
        self.0.predict(&f, T::from_f64(lambda))
    }
    fn time_update(&mut self, q: &[f64]) -> Result<bool, String> {
        let q = Vector::<T, N>::from_column(core::array::from_fn(|i| T::from_f64(q[i])));
        self.0.time_update(&q)
    }
}

fn build_form<T, const N: usize>(
    form: &str,
    x0: &[f64],
    p0: &[f64],
    config: RlsConfig,
) -> PyResult<Box<dyn DynRls>>
where
    T: Lane<Scalar = T> + Send + Sync,
{
    let x = Vector::<T, N>::from_column(core::array::from_fn(|i| T::from_f64(x0[i])));
    let p = Mat::<T, N, N>::from_fn(|r, c| T::from_f64(p0[r * N + c]));
    fn boxed<T, const N: usize, R>(
        r: Result<R, rootfuse_lsq::rls::RlsError>,
    ) -> PyResult<Box<dyn DynRls>>
    where
        T: Lane<Scalar = T> + Send + Sync,
        R: RecursiveLeastSquares<T, N> + TimeUpdates<T, N> + Send + Sync + 'static,
    {
        r.map(|r| Box::new(Typed::<T, N, R>(r, core::marker::PhantomData)) as Box<dyn DynRls>)
            .map_err(|e| PyValueError::new_err(format!("Rls: {e}")))
    }
    match form {
        "conventional" => boxed::<T, N, _>(Conventional::<T, N>::new(&x, &p, config)),
        "joseph" => boxed::<T, N, _>(Joseph::<T, N>::new(&x, &p, config)),
        "potter" => boxed::<T, N, _>(Potter::<T, N>::new(&x, &p, config)),
        "bierman-ud" => boxed::<T, N, _>(BiermanUd::<T, N>::new(&x, &p, config)),
        "inverse-qr" => boxed::<T, N, _>(InverseQr::<T, N>::new(&x, &p, config)),
        "information-qr" => boxed::<T, N, _>(InformationQr::<T, N>::new(&x, &p, config)),
        _ => Err(PyValueError::new_err(format!(
            "form: unknown form {form:?} (valid: {})",
            FORMS.join(", ")
        ))),
    }
}

fn build(
    form: &str,
    n: usize,
    prec: Precision,
    x0: &[f64],
    p0: &[f64],
    config: RlsConfig,
) -> PyResult<Box<dyn DynRls>> {
    macro_rules! sizes {
        ($($k:literal)*) => {
            match (n, prec) {
                $( ($k, Precision::F32) => build_form::<f32, $k>(form, x0, p0, config),
                   ($k, Precision::F64) => build_form::<f64, $k>(form, x0, p0, config), )*
                _ => Err(PyValueError::new_err(format!(
                    "n: expected a state size from 1 to {MAX_N}, got {n}"
                ))),
            }
        };
    }
    sizes!(1 2 3 4 5 6 7 8)
}

/// A recursive least-squares estimator: one of the six forms (`"conventional"`, `"joseph"`,
/// `"potter"`, `"bierman-ud"`, `"inverse-qr"`, `"information-qr"`), state size `n` = 1..8,
/// f32 or f64.
///
/// `Rls(form, n, *, x0=None, p0=None, lam=1.0, p_min=None, p_max=None, compensated=True,
/// precision="f64")`: prior estimate `x0` (`(n,)`, zeros by default) and covariance `p0`
/// (None for `1e6·I`, a number for `p0·I`, or `(n, n)` symmetric, squared units of x: an asymmetry beyond 1e-9 of
/// its largest entry is a ValueError naming the worst pair); forgetting factor `lam` in (0, 1]
/// (memory about 1/(1−lam) samples); optional windup protection keeping every eigenvalue of
/// P in `[p_min, p_max]`; `compensated` selects compensated sums in the information form.
///
/// Measurements `z = hᵀx + v` with weight `1/var(v)`. A sample with non-finite data or a weight
/// `≤ 0` is rejected and counted (`health["rejected_input"]`), never an exception.
#[pyclass(module = "rootfuse._rootfuse")]
pub struct Rls {
    inner: Box<dyn DynRls>,
    precision: Precision,
}

#[pymethods]
impl Rls {
    #[new]
    #[pyo3(signature = (form, n, *, x0=None, p0=None, lam=1.0, p_min=None, p_max=None, compensated=true, precision="f64"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        form: &str,
        #[pyo3(from_py_with = whole)] n: usize,
        x0: Option<&Bound<'_, PyAny>>,
        p0: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = real)] lam: f64,
        #[pyo3(from_py_with = real_or_none)] p_min: Option<f64>,
        #[pyo3(from_py_with = real_or_none)] p_max: Option<f64>,
        compensated: bool,
        precision: &str,
    ) -> PyResult<Self> {
        let prec = self::precision(precision)?;
        if !(1..=MAX_N).contains(&n) {
            return Err(PyValueError::new_err(format!(
                "n: expected a state size from 1 to {MAX_N}, got {n}"
            )));
        }
        let x0 = match x0 {
            Some(x) => {
                let v = vector(x, "x0")?;
                if v.len() != n {
                    return Err(PyValueError::new_err(format!(
                        "x0: expected shape ({n},), got ({},)",
                        v.len()
                    )));
                }
                v
            }
            None => vec![0.0; n],
        };
        let p0 = match p0 {
            None => identity(n, 1e6),
            Some(p) if is_bool(p) => {
                return Err(PyTypeError::new_err(
                    "p0: expected a number or an (n, n) matrix, got a bool: booleans are not numbers here",
                ));
            }
            Some(p) => match p.extract::<f64>() {
                Ok(s) if p.cast::<numpy::PyUntypedArray>().is_err() => {
                    if !(s.is_finite() && s > 0.0) {
                        return Err(PyValueError::new_err(format!(
                            "p0: expected a finite number > 0 or an (n, n) positive definite matrix, got {s}"
                        )));
                    }
                    identity(n, s)
                }
                _ => {
                    let m = square(p, "p0", n)?;
                    // The forms read one triangle: an asymmetric prior would be used halfway.
                    symmetric(&m, n, "p0")?;
                    m
                }
            },
        };
        let mut config = RlsConfig::new(lam);
        if !compensated {
            config = config.without_compensation();
        }
        match (p_min, p_max) {
            (None, None) => {}
            (lo, hi) => config = config.with_bounds(lo.unwrap_or(0.0), hi.unwrap_or(f64::INFINITY)),
        }
        Ok(Self {
            inner: build(form, n, prec, &x0, &p0, config)?,
            precision: prec,
        })
    }

    /// The form's name.
    #[getter]
    fn form(&self) -> &'static str {
        self.inner.name()
    }

    /// The state size n.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n()
    }

    /// `"f32"` or `"f64"`.
    #[getter]
    fn precision(&self) -> &'static str {
        match self.precision {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }

    /// One scalar measurement `z = hᵀx + v` (h: `(n,)`, weight `1/var(v)`), forgetting first.
    /// Returns True if applied, False if rejected (counted in `health`).
    #[pyo3(signature = (h, z, weight=1.0))]
    fn update(
        &mut self,
        h: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = real)] z: f64,
        #[pyo3(from_py_with = real)] weight: f64,
    ) -> PyResult<bool> {
        let h = vector(h, "h")?;
        check_n("h", h.len(), self.inner.n())?;
        Ok(self.inner.update(&h, z, weight))
    }

    /// Runs K measurements in order with the GIL released: `h` `(K, n)`, `z` `(K,)`,
    /// `weights` a number or `(K,)`. Returns a dict: `estimate` `(K, n)` after each step,
    /// `accepted` `(K,)` bool, `min_pivot`, `max_pivot`, `trace` `(K,)` (health after each
    /// step, units of P), `lost_definiteness` `(K,)` bool (sticky failure flag of the
    /// covariance forms).
    #[pyo3(signature = (h, z, weights=None))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        h: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        weights: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = self.inner.n();
        let ha = float_array(h, "h")?;
        let k = match *ha.shape.as_slice() {
            [k, c] if c == n => k,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "h: expected shape (K, {n}), got {:?}",
                    ha.shape
                )));
            }
        };
        let z = vector(z, "z")?;
        check_len("z", z.len(), k)?;
        let w = match weights {
            None => vec![1.0; k],
            Some(w) if is_bool(w) => {
                return Err(PyTypeError::new_err(
                    "weights: expected a number or a (K,) array, got a bool: booleans are not numbers here",
                ));
            }
            Some(w) => match w.extract::<f64>() {
                Ok(s) if w.cast::<numpy::PyUntypedArray>().is_err() => vec![s; k],
                _ => {
                    let v = vector(w, "weights")?;
                    check_len("weights", v.len(), k)?;
                    v
                }
            },
        };
        let hs = ha.as_slice();
        let inner = &mut self.inner;
        let (est, acc, minp, maxp, tr, lost) = py.detach(|| {
            let mut est = Vec::with_capacity(k * n);
            let (mut acc, mut minp, mut maxp, mut tr, mut lost) = (
                Vec::with_capacity(k),
                Vec::with_capacity(k),
                Vec::with_capacity(k),
                Vec::with_capacity(k),
                Vec::with_capacity(k),
            );
            for i in 0..k {
                acc.push(inner.update(&hs[i * n..(i + 1) * n], z[i], w[i]));
                est.extend(inner.estimate());
                let hl = inner.health();
                minp.push(hl.min_pivot);
                maxp.push(hl.max_pivot);
                tr.push(hl.trace);
                lost.push(hl.lost_definiteness);
            }
            (est, acc, minp, maxp, tr, lost)
        });
        let out = PyDict::new(py);
        out.set_item("estimate", PyArray1::from_vec(py, est).reshape([k, n])?)?;
        out.set_item("accepted", PyArray1::from_vec(py, acc))?;
        out.set_item("min_pivot", PyArray1::from_vec(py, minp))?;
        out.set_item("max_pivot", PyArray1::from_vec(py, maxp))?;
        out.set_item("trace", PyArray1::from_vec(py, tr))?;
        out.set_item("lost_definiteness", PyArray1::from_vec(py, lost))?;
        Ok(out)
    }

    /// Potter form only: a known state transition between measurements, `x ← F x`,
    /// `P ← F P Fᵀ / lam` (`f` `(n, n)`, `lam` in (0, 1], 1 = no forgetting). Returns True if
    /// applied, False if `f`/`lam` were not usable or the result not finite (counted in
    /// `health`). ValueError for another form, or when covariance bounds are set (a general
    /// transition would void them).
    #[pyo3(signature = (f, lam=1.0))]
    fn predict(
        &mut self,
        f: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = real)] lam: f64,
    ) -> PyResult<bool> {
        let n = self.inner.n();
        let f = square(f, "f", n)?;
        self.inner
            .predict(&f, lam)
            .map_err(|e| PyValueError::new_err(format!("predict: {e}")))
    }

    /// Bierman U-D form only: process noise `Q = diag(q)` added to `P` (`q` `(n,)`, variances
    /// in units of P, ≥ 0) by Thornton's square-root-free time update. With covariance bounds
    /// `q` is scaled down so that `trace(P) ≤ p_max` still holds. Returns True if applied,
    /// False for a negative or non-finite `q` (counted as rejected input). ValueError for
    /// another form.
    fn time_update(&mut self, q: &Bound<'_, PyAny>) -> PyResult<bool> {
        let q = vector(q, "q")?;
        check_n("q", q.len(), self.inner.n())?;
        self.inner
            .time_update(&q)
            .map_err(|e| PyValueError::new_err(format!("time_update: {e}")))
    }

    /// The current estimate x, float64 `(n,)`.
    #[getter]
    fn estimate<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.estimate())
    }

    /// The covariance P (formed from the factor for the factored forms), float64 `(n, n)`.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.inner.n();
        Ok(PyArray1::from_vec(py, self.inner.covariance())
            .reshape([n, n])?
            .into_any())
    }

    /// Diagnostics: `min_pivot`, `max_pivot`, `pivot_ratio` (a lower bound of cond(P)),
    /// `trace`, `information_trace`, `lost_definiteness`, and the counts `accepted`,
    /// `rejected_input`, `rejected_numerical`, `clipped`.
    #[getter]
    fn health<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let h = self.inner.health();
        let d = PyDict::new(py);
        d.set_item("min_pivot", h.min_pivot)?;
        d.set_item("max_pivot", h.max_pivot)?;
        d.set_item("pivot_ratio", h.max_pivot / h.min_pivot)?;
        d.set_item("trace", h.trace)?;
        d.set_item("information_trace", h.information_trace)?;
        d.set_item("lost_definiteness", h.lost_definiteness)?;
        d.set_item("accepted", h.accepted)?;
        d.set_item("rejected_input", h.rejected_input)?;
        d.set_item("rejected_numerical", h.rejected_numerical)?;
        d.set_item("clipped", h.clipped)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Rls({:?}, n={}, precision={:?})",
            self.form(),
            self.n(),
            self.precision()
        )
    }
}

fn identity(n: usize, s: f64) -> Vec<f64> {
    (0..n * n)
        .map(|i| if i / n == i % n { s } else { 0.0 })
        .collect()
}

fn check_n(name: &str, got: usize, n: usize) -> PyResult<()> {
    if got == n {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "{name}: expected shape ({n},), got ({got},)"
        )))
    }
}

fn check_len(name: &str, got: usize, k: usize) -> PyResult<()> {
    if got == k {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "{name}: has {got} entries but h has {k} rows"
        )))
    }
}

fn method(text: &str) -> PyResult<Method> {
    match text {
        "qr" => Ok(Method::Qr),
        "pivoted-qr" => Ok(Method::PivotedQr),
        "svd" => Ok(Method::Svd),
        "normal-equations" => Ok(Method::NormalEquations),
        _ => Err(PyValueError::new_err(format!(
            "method: expected \"qr\", \"pivoted-qr\", \"svd\" or \"normal-equations\", got {text:?}"
        ))),
    }
}

fn solve_typed<'py, T: LsqReal>(
    py: Python<'py>,
    h: &[f64],
    (m, n): (usize, usize),
    z: &[f64],
    w: &LsqWeights,
    options: Options<T>,
) -> PyResult<Bound<'py, PyDict>> {
    let cast = |x: f64| <T as LsqReal>::from_f64(x);
    let hm = faer::Mat::<T>::from_fn(m, n, |i, j| cast(h[i * n + j]));
    let zc = faer::Col::<T>::from_fn(m, |i| cast(z[i]));
    let wd;
    let rm;
    let weights = match w {
        LsqWeights::Unit => Weights::Unit,
        LsqWeights::Diagonal(v) => {
            wd = faer::Col::<T>::from_fn(v.len(), |i| cast(v[i]));
            Weights::Diagonal(wd.as_ref())
        }
        LsqWeights::Covariance(r, k) => {
            rm = faer::Mat::<T>::from_fn(*k, *k, |i, j| cast(r[i * k + j]));
            Weights::Covariance(rm.as_ref())
        }
    };
    let sol = py
        .detach(|| dense::solve(hm.as_ref(), zc.as_ref(), weights, &options))
        .map_err(|e| PyValueError::new_err(format!("lstsq: {e}")))?;
    let f = |x: T| -> f64 { LsqReal::to_f64(x) };
    let d = PyDict::new(py);
    d.set_item(
        "estimate",
        PyArray1::from_vec(py, (0..n).map(|i| f(sol.estimate[i])).collect()),
    )?;
    d.set_item(
        "residuals",
        PyArray1::from_vec(py, (0..m).map(|i| f(sol.residuals[i])).collect()),
    )?;
    let cov: Vec<f64> = (0..n * n)
        .map(|i| f(sol.covariance[(i / n, i % n)]))
        .collect();
    d.set_item("covariance", PyArray1::from_vec(py, cov).reshape([n, n])?)?;
    d.set_item("rss", f(sol.rss))?;
    d.set_item("dof", sol.dof)?;
    d.set_item("residual_variance", sol.residual_variance.map(f))?;
    d.set_item("r_squared", sol.r_squared.map(f))?;
    d.set_item("condition", f(sol.condition))?;
    d.set_item("rank", sol.rank)?;
    Ok(d)
}

enum LsqWeights {
    Unit,
    Diagonal(Vec<f64>),
    Covariance(Vec<f64>, usize),
}

/// Weighted linear least squares `min ‖W^½ (z − H x)‖₂` by a dense factorisation.
///
/// `h` `(m, n)`, `z` `(m,)`; `weights` `(m,)` (`W = diag(w)`, `w ≥ 0`) or `covariance`
/// `(m, m)` (`W = R⁻¹`, R symmetric positive definite: an asymmetry beyond 1e-9 of its
/// largest entry is a ValueError naming the worst pair), not both. `method`: `"qr"` (full
/// rank required), `"pivoted-qr"` (basic solution when rank deficient), `"svd"`
/// (minimum-norm solution) or `"normal-equations"` (a comparison: raises ValueError
/// reporting Cholesky breakdown or ill-conditioning where it would lose every digit).
/// `rank_tolerance`: relative, finite and ≥ 0 (None: `max(m, n)·ε`). Returns a dict:
/// `estimate` `(n,)`, `residuals` `(m,)` (unweighted), `covariance` `(n, n)` = `(HᵀWH)⁻¹`
/// (not scaled by the residual variance), `rss`, `dof`, `residual_variance`, `r_squared`,
/// `condition`, `rank`. Every failure (sizes, non-finite values naming their position, rank
/// deficiency, breakdown) is a ValueError.
#[pyfunction]
#[pyo3(signature = (h, z, *, weights=None, covariance=None, method="qr", rank_tolerance=None, equilibrate=true, refinement_steps=3, precision="f64"))]
#[allow(clippy::too_many_arguments)]
pub fn lstsq<'py>(
    py: Python<'py>,
    h: &Bound<'py, PyAny>,
    z: &Bound<'py, PyAny>,
    weights: Option<&Bound<'py, PyAny>>,
    covariance: Option<&Bound<'py, PyAny>>,
    method: &str,
    #[pyo3(from_py_with = real_or_none)] rank_tolerance: Option<f64>,
    equilibrate: bool,
    #[pyo3(from_py_with = whole)] refinement_steps: usize,
    precision: &str,
) -> PyResult<Bound<'py, PyDict>> {
    if let Some(tol) = rank_tolerance
        && !(tol.is_finite() && tol >= 0.0)
    {
        return Err(PyValueError::new_err(format!(
            "rank_tolerance: expected a finite number ≥ 0 (relative to the largest diagonal entry of R or singular value; None: max(m, n)·ε), got {tol}"
        )));
    }
    let ha = float_array(h, "h")?;
    let (m, n) = match *ha.shape.as_slice() {
        [m, n] => (m, n),
        _ => {
            return Err(PyValueError::new_err(format!(
                "h: expected shape (m, n), got {:?}",
                ha.shape
            )));
        }
    };
    let z = vector(z, "z")?;
    if z.len() != m {
        return Err(PyValueError::new_err(format!(
            "z: has {} entries but h has {m} rows",
            z.len()
        )));
    }
    let w = match (weights, covariance) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "weights, covariance: give one of them, not both",
            ));
        }
        (Some(w), None) => {
            let v = vector(w, "weights")?;
            if v.len() != m {
                return Err(PyValueError::new_err(format!(
                    "weights: has {} entries but h has {m} rows",
                    v.len()
                )));
            }
            LsqWeights::Diagonal(v)
        }
        (None, Some(r)) => {
            let r = square(r, "covariance", m)?;
            // The solver factors one triangle: an asymmetric R would be used halfway.
            symmetric(&r, m, "covariance")?;
            LsqWeights::Covariance(r, m)
        }
        (None, None) => LsqWeights::Unit,
    };
    let method = self::method(method)?;
    match self::precision(precision)? {
        Precision::F64 => {
            let options = Options::<f64> {
                method,
                rank_tolerance,
                equilibrate,
                refinement_steps,
                ..Options::default()
            };
            solve_typed(py, ha.as_slice(), (m, n), &z, &w, options)
        }
        Precision::F32 => {
            let options = Options::<f32> {
                method,
                rank_tolerance: rank_tolerance.map(|x| x as f32),
                equilibrate,
                refinement_steps,
                ..Options::default()
            };
            solve_typed(py, ha.as_slice(), (m, n), &z, &w, options)
        }
    }
}

/// The recursive forms under numerical stress against a double-double reference
/// (`rootfuse_lsq::stress`, what `rootfuse stress` prints). `scenario`: one of
/// `stress_scenarios()` or None for all; `scale` multiplies every step count (1.0 = the
/// documented lengths, about a minute in all; 0.01 for a quick look); `long` runs `benign` and
/// `lambda-one` ten times longer. Returns one dict per form, precision and scenario parameter:
/// `form`, `precision`, `scenario`, `param`, `steps`, `max_rel_err`, `pd_lost_at`, `nan_at`,
/// `detected`, `ns_per_update`, `trace` (list of `(step, rel_err)`).
#[pyfunction]
#[pyo3(signature = (scenario=None, *, scale=1.0, long=false))]
pub fn stress<'py>(
    py: Python<'py>,
    scenario: Option<&str>,
    #[pyo3(from_py_with = real)] scale: f64,
    long: bool,
) -> PyResult<Bound<'py, PyList>> {
    crate::arrays::positive(scale, "scale")?;
    if scale > rootfuse_lsq::stress::MAX_SCALE {
        return Err(PyValueError::new_err(format!(
            "scale: at most {} (minutes per scenario, and the run cannot be interrupted), got {scale}",
            rootfuse_lsq::stress::MAX_SCALE
        )));
    }
    let options = rootfuse_lsq::stress::StressOptions { long, scale };
    let rows = match scenario {
        None => py.detach(|| rootfuse_lsq::stress::run_all(options)),
        Some(name) => py
            .detach(|| rootfuse_lsq::stress::run_scenario(name, options))
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "scenario: unknown {name:?} (valid: {})",
                    rootfuse_lsq::stress::SCENARIOS.join(", ")
                ))
            })?,
    };
    let out = PyList::empty(py);
    for r in rows {
        let d = PyDict::new(py);
        d.set_item("form", r.form)?;
        d.set_item("precision", r.precision)?;
        d.set_item("scenario", r.scenario)?;
        d.set_item("param", r.param)?;
        d.set_item("steps", r.steps)?;
        d.set_item("max_rel_err", r.max_rel_err)?;
        d.set_item("pd_lost_at", r.pd_lost_at)?;
        d.set_item("nan_at", r.nan_at)?;
        d.set_item("detected", r.detected)?;
        d.set_item("ns_per_update", r.ns_per_update)?;
        d.set_item("trace", r.trace)?;
        out.append(d)?;
    }
    Ok(out)
}

/// The stress scenario names.
#[pyfunction]
pub fn stress_scenarios() -> Vec<&'static str> {
    rootfuse_lsq::stress::SCENARIOS.to_vec()
}

/// The recursive form names `Rls` accepts.
#[pyfunction]
pub fn rls_forms() -> Vec<&'static str> {
    FORMS.to_vec()
}
