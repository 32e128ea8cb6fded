//! Small dense 3×3 and 3-vector helpers on plain arrays, shared by the fit and its quality
//! figures.

use rootfuse_lsq::dense::faer::{Mat, Side};

/// Eigen-decomposition of a symmetric 3×3 matrix: eigenvalues ascending and the eigenvectors
/// as columns.
pub(crate) fn sym_eigen(a: [[f64; 3]; 3]) -> Option<([f64; 3], [[f64; 3]; 3])> {
    let m = Mat::<f64>::from_fn(3, 3, |i, j| a[i][j]);
    let evd = m.self_adjoint_eigen(Side::Lower).ok()?;
    let vals = core::array::from_fn(|i| evd.S()[i]);
    let vecs = core::array::from_fn(|i| core::array::from_fn(|j| evd.U()[(i, j)]));
    Some((vals, vecs))
}

/// `f(A) = V·diag(f)·Vᵀ` for eigenvectors `V` (columns).
pub(crate) fn sym_function(vecs: &[[f64; 3]; 3], f: &[f64; 3]) -> [[f64; 3]; 3] {
    core::array::from_fn(|i| {
        core::array::from_fn(|j| (0..3).map(|k| vecs[i][k] * f[k] * vecs[j][k]).sum())
    })
}

/// `f(A)·x` for eigenvectors `V` (columns) of `A`.
pub(crate) fn sym_apply(vecs: &[[f64; 3]; 3], f: &[f64; 3], x: [f64; 3]) -> [f64; 3] {
    mat_vec(&sym_function(vecs, f), x)
}

/// `M·v`.
pub(crate) fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    core::array::from_fn(|i| dot3(m[i], v))
}

/// `a·b`.
pub(crate) fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a − b`.
pub(crate) fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `|a|` (overflows to ∞ for components beyond about 1e154).
pub(crate) fn norm3(a: [f64; 3]) -> f64 {
    dot3(a, a).sqrt()
}

/// `det M`.
pub(crate) fn det3(m: &[[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Squared Euclidean distance.
pub(crate) fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum()
}
