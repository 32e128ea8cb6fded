//! The four factorisations, each solving the whitened, column-equilibrated problem
//! `min ‖b − A y‖` and returning `y`, `(AᵀA)⁻¹` (or its rank-truncated form), rank and condition.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::householder;
use faer::linalg::solvers::{ColPivQr, Llt, LltError, Qr, Svd};
use faer::{Col, ColRef, Conj, Mat, MatRef, Par, Side};

use super::refine::{QrParts, SvdParts, refine};
use super::{LsqError, LsqReal};

/// What every method hands back, in the equilibrated coordinates.
pub(super) struct Factored<T> {
    pub y: Col<T>,
    pub cov: Mat<T>,
    pub rank: usize,
    pub condition: T,
}

fn infinity<T: LsqReal>() -> T {
    T::from_f64(f64::INFINITY)
}

/// `Qᵀ b` for a Householder sequence stored the way faer's QR factorisations store it.
fn apply_qt<T: LsqReal>(basis: MatRef<'_, T>, coeff: MatRef<'_, T>, b: ColRef<'_, T>) -> Col<T> {
    let m = b.nrows();
    let mut c = Mat::<T>::from_fn(m, 1, |i, _| b[i]);
    let mut mem = MemBuffer::new(
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<T>(
            m,
            coeff.nrows(),
            1,
        ),
    );
    householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
        basis,
        coeff,
        Conj::No,
        c.as_mut(),
        Par::Seq,
        MemStack::new(&mut mem),
    );
    Col::from_fn(m, |i| c[(i, 0)])
}

/// `R⁻¹` of a nonsingular upper-triangular `R`.
fn upper_inverse<T: LsqReal>(r: MatRef<'_, T>) -> Mat<T> {
    let n = r.nrows();
    let mut inv = Mat::<T>::identity(n, n);
    r.solve_upper_triangular_in_place(inv.as_mut());
    inv
}

fn norm1<T: LsqReal>(a: MatRef<'_, T>) -> T {
    let mut best = T::zero_impl();
    for j in 0..a.ncols() {
        let mut s = T::zero_impl();
        for i in 0..a.nrows() {
            s += a[(i, j)].abs();
        }
        if s > best {
            best = s;
        }
    }
    best
}

/// `M Mᵀ`, the covariance from an inverse (square-root) factor.
fn outer<T: LsqReal>(m: MatRef<'_, T>) -> Mat<T> {
    let mut out = Mat::<T>::zeros(m.nrows(), m.nrows());
    faer::linalg::matmul::matmul(
        out.as_mut(),
        faer::Accum::Replace,
        m,
        m.transpose(),
        T::one_impl(),
        Par::Seq,
    );
    out
}

/// `κ₁(R) = ‖R‖₁ ‖R⁻¹‖₁`: exact for the 1-norm, within a factor `n` of `κ₂`, and cheap once
/// `R⁻¹` is formed for the covariance anyway.
fn condition_1<T: LsqReal>(r: MatRef<'_, T>, r_inv: MatRef<'_, T>) -> T {
    let c = norm1(r) * norm1(r_inv);
    if c.is_finite() { c } else { infinity() }
}

/// Refinement converges at a rate of about `κ·ε` per step; beyond `κ·ε ≈ 10⁻²` it may not pay.
fn refinable<T: LsqReal>(condition: T) -> bool {
    condition * T::EPSILON < T::from_f64(1e-2)
}

/// Rank from the diagonal of a triangular factor: the leading entries above `tol · max |r_kk|`.
fn diagonal_rank<T: LsqReal>(r: MatRef<'_, T>, tol: T) -> usize {
    let n = r.ncols().min(r.nrows());
    let mut big = T::zero_impl();
    for k in 0..n {
        let v = r[(k, k)].abs();
        if v > big {
            big = v;
        }
    }
    let cut = tol * big;
    (0..n).take_while(|&k| r[(k, k)].abs() > cut).count()
}

/// Householder QR without pivoting: the default, backward stable, full rank assumed.
pub(super) fn qr<T: LsqReal>(
    a: MatRef<'_, T>,
    b: ColRef<'_, T>,
    tol: T,
    refinement_steps: usize,
) -> Result<Factored<T>, LsqError> {
    let n = a.ncols();
    let f = Qr::new(a);
    let r = f.thin_R();
    let rank = diagonal_rank(r, tol);
    if rank < n {
        return Err(LsqError::RankDeficient { rank, cols: n });
    }
    let c = apply_qt(f.Q_basis(), f.Q_coeff(), b);
    let mut y = Mat::<T>::from_fn(n, 1, |i, _| c[i]);
    r.solve_upper_triangular_in_place(y.as_mut());
    let r_inv = upper_inverse(r);
    let condition = condition_1(r, r_inv.as_ref());
    let mut y = Col::from_fn(n, |i| y[(i, 0)]);
    if refinable(condition) {
        let cols: Vec<usize> = (0..n).collect();
        let parts = QrParts {
            basis: f.Q_basis(),
            coeff: f.Q_coeff(),
            r,
            cols: &cols,
        };
        refine(a, b, &parts, &mut y, refinement_steps);
    }
    Ok(Factored {
        y,
        cov: outer(r_inv.as_ref()),
        rank,
        condition,
    })
}

/// Column-pivoted QR: `A P = Q R` with non-increasing `|r_kk|`; the trailing block below the rank
/// tolerance is treated as zero, which gives the basic solution (zeros in the dropped parameters).
pub(super) fn pivoted_qr<T: LsqReal>(
    a: MatRef<'_, T>,
    b: ColRef<'_, T>,
    tol: T,
    refinement_steps: usize,
) -> Result<Factored<T>, LsqError> {
    let n = a.ncols();
    let f = ColPivQr::new(a);
    let r = f.thin_R();
    let rank = diagonal_rank(r, tol);
    let c = apply_qt(f.Q_basis(), f.Q_coeff(), b);
    let r11 = r.get(..rank, ..rank);
    let mut y11 = Mat::<T>::from_fn(rank, 1, |i, _| c[i]);
    r11.solve_upper_triangular_in_place(y11.as_mut());
    let r11_inv = upper_inverse(r11);
    let cov11 = outer(r11_inv.as_ref());

    // Column k of `A P` is column `fwd[k]` of `A`.
    let (fwd, _) = f.P().arrays();
    let mut y = Col::<T>::zeros(n);
    let mut cov = Mat::<T>::zeros(n, n);
    for k in 0..rank {
        y[fwd[k]] = y11[(k, 0)];
        for l in 0..rank {
            cov[(fwd[k], fwd[l])] = cov11[(k, l)];
        }
    }
    let condition = if rank == n {
        condition_1(r, r11_inv.as_ref())
    } else {
        infinity()
    };
    if rank == n && refinable(condition) {
        let cols: Vec<usize> = fwd.to_vec();
        let parts = QrParts {
            basis: f.Q_basis(),
            coeff: f.Q_coeff(),
            r,
            cols: &cols,
        };
        refine(a, b, &parts, &mut y, refinement_steps);
    }
    Ok(Factored {
        y,
        cov,
        rank,
        condition,
    })
}

/// Thin SVD: singular values below `tol · σ_max` are dropped, which gives the minimum-norm
/// solution and the pseudo-inverse of `AᵀA` as covariance.
pub(super) fn svd<T: LsqReal>(
    a: MatRef<'_, T>,
    b: ColRef<'_, T>,
    tol: T,
    refinement_steps: usize,
) -> Result<Factored<T>, LsqError> {
    let n = a.ncols();
    let f = Svd::new_thin(a).map_err(|_| LsqError::SvdNoConvergence)?;
    let s = f.S().column_vector();
    let (u, v) = (f.U(), f.V());
    let mut s_max = T::zero_impl();
    let mut s_min = infinity::<T>();
    for k in 0..s.nrows() {
        if s[k] > s_max {
            s_max = s[k];
        }
        if s[k] < s_min {
            s_min = s[k];
        }
    }
    let cut = tol * s_max;
    let mut y = Col::<T>::zeros(n);
    // V Σ⁻¹ restricted to the kept singular triplets: y = M Uᵀb and cov = M Mᵀ.
    let mut m = Mat::<T>::zeros(n, n);
    let mut rank = 0;
    for k in 0..s.nrows() {
        if s[k] <= cut {
            continue;
        }
        rank += 1;
        let mut utb = T::zero_impl();
        for i in 0..u.nrows() {
            utb += u[(i, k)] * b[i];
        }
        let inv_s = T::one_impl() / s[k];
        for i in 0..n {
            m[(i, k)] = v[(i, k)] * inv_s;
            y[i] += m[(i, k)] * utb;
        }
    }
    let condition = if s_min > T::zero_impl() {
        s_max / s_min
    } else {
        infinity()
    };
    if rank == n && refinable(condition) {
        let parts = SvdParts {
            u: u.get(.., ..n),
            s,
            v: v.get(.., ..n),
        };
        refine(a, b, &parts, &mut y, refinement_steps);
    }
    Ok(Factored {
        y,
        cov: outer(m.as_ref()),
        rank,
        condition: if condition.is_finite() {
            condition
        } else {
            infinity()
        },
    })
}

/// Normal equations `AᵀA y = Aᵀb` by Cholesky, kept as a comparison method: it squares the
/// condition number, so it refuses (with a typed error) instead of returning digits it lost.
pub(super) fn normal_equations<T: LsqReal>(
    a: MatRef<'_, T>,
    b: ColRef<'_, T>,
) -> Result<Factored<T>, LsqError> {
    let (m, n) = (a.nrows(), a.ncols());
    let mut g = Mat::<T>::zeros(n, n);
    faer::linalg::matmul::matmul(
        g.as_mut(),
        faer::Accum::Replace,
        a.transpose(),
        a,
        T::one_impl(),
        Par::Seq,
    );
    let mut rhs = Mat::<T>::zeros(n, 1);
    for j in 0..n {
        let mut s = T::zero_impl();
        for i in 0..m {
            s += a[(i, j)] * b[i];
        }
        rhs[(j, 0)] = s;
    }
    let llt = Llt::new(g.as_ref(), Side::Lower).map_err(|e| match e {
        LltError::NonPositivePivot { index } => LsqError::Breakdown { pivot: index },
    })?;
    let l = llt.L();
    // A pivot l_kk² is g_kk minus the squares above it; when that difference is below n·ε·g_kk it
    // is rounding noise, and everything solved from it would be too.
    let n_eps = T::from_f64(n as f64) * T::EPSILON;
    for k in 0..n {
        // Written as an acceptance test so that a NaN pivot is rejected too.
        let accepted = l[(k, k)] * l[(k, k)] > n_eps * g[(k, k)];
        if !accepted {
            return Err(LsqError::Breakdown { pivot: k });
        }
    }
    let r = l.transpose().to_owned();
    let r_inv = upper_inverse(r.as_ref());
    let condition = condition_1(r.as_ref(), r_inv.as_ref());
    let accepted = condition * condition * T::EPSILON < T::one_impl();
    if !accepted {
        return Err(LsqError::IllConditioned {
            condition: condition.to_f64(),
        });
    }
    l.solve_lower_triangular_in_place(rhs.as_mut());
    r.as_ref().solve_upper_triangular_in_place(rhs.as_mut());
    Ok(Factored {
        y: Col::from_fn(n, |i| rhs[(i, 0)]),
        cov: outer(r_inv.as_ref()),
        rank: n,
        condition,
    })
}
