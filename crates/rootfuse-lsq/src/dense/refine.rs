//! Iterative refinement of a QR least-squares solution on the augmented system
//! `[I A; Aᵀ 0] [r; y] = [b; 0]` (Björck 1967), with residuals accumulated in twice the working
//! precision.
//!
//! Why: a backward-stable QR solution carries an error term `κ(A)²·ε·‖r‖/(‖A‖‖y‖)`, which
//! dominates when the residual is large (NIST Wampler4/5 lose two digits to it). Refining only
//! `y` from `b − A y` cannot remove it, because that residual is itself large; refining `r` and `y`
//! together with accurately computed `f = b − r − A y` and `g = −Aᵀ r` converges to the solution of
//! the rounded problem at a rate of about `κ(A)·ε` per step.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::householder;
use faer::{Col, ColRef, Conj, Mat, MatRef, Par};

use super::LsqReal;

/// A running sum kept as an unevaluated pair `s + c` (Ogita, Rump & Oishi's Sum2/Dot2): the
/// result is as accurate as if computed in twice the working precision, then rounded once.
#[derive(Clone, Copy)]
struct Compensated<T> {
    s: T,
    c: T,
}

impl<T: LsqReal> Compensated<T> {
    fn new() -> Self {
        Compensated {
            s: T::zero_impl(),
            c: T::zero_impl(),
        }
    }

    fn add(&mut self, x: T) {
        let s = self.s + x;
        let bb = s - self.s;
        self.c += (self.s - (s - bb)) + (x - bb);
        self.s = s;
    }

    fn add_product(&mut self, a: T, b: T) {
        let p = a * b;
        self.add(p);
        self.c += a.fused_mul_add(b, -p);
    }

    fn value(self) -> T {
        self.s + self.c
    }
}

/// A QR factorisation `A P = Q R` as faer stores it. `cols[k]` is the column of `A` that is column
/// `k` of `A P`.
pub(super) struct QrParts<'a, T> {
    pub basis: MatRef<'a, T>,
    pub coeff: MatRef<'a, T>,
    pub r: MatRef<'a, T>,
    pub cols: &'a [usize],
}

fn apply_q<T: LsqReal>(q: &QrParts<'_, T>, v: &mut Mat<T>, transpose: bool) {
    let m = v.nrows();
    let bs = q.coeff.nrows();
    if transpose {
        let mut mem = MemBuffer::new(
            householder::apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<T>(
                m, bs, 1,
            ),
        );
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            q.basis,
            q.coeff,
            Conj::No,
            v.as_mut(),
            Par::Seq,
            MemStack::new(&mut mem),
        );
    } else {
        let mut mem = MemBuffer::new(
            householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<T>(
                m, bs, 1,
            ),
        );
        householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
            q.basis,
            q.coeff,
            Conj::No,
            v.as_mut(),
            Par::Seq,
            MemStack::new(&mut mem),
        );
    }
}

/// A factorisation that solves the augmented correction system
/// `[I A; Aᵀ 0] [δr; δy] = [f; g]` (`g` and `δy` in the original column order).
pub(super) trait Augmented<T> {
    fn solve(&self, f: &Col<T>, g: &Col<T>) -> (Col<T>, Col<T>);
}

impl<T: LsqReal> Augmented<T> for QrParts<'_, T> {
    fn solve(&self, f: &Col<T>, g: &Col<T>) -> (Col<T>, Col<T>) {
        let (m, n) = (f.nrows(), g.nrows());
        // With Qᵀ δr = [u; v]: Rᵀ u = Pᵀ g, v = (Qᵀ f)₂, R Pᵀ δy = (Qᵀ f)₁ − u.
        let mut ft = Mat::<T>::from_fn(m, 1, |i, _| f[i]);
        apply_q(self, &mut ft, true);
        let mut u = Mat::<T>::from_fn(n, 1, |k, _| g[self.cols[k]]);
        self.r
            .transpose()
            .solve_lower_triangular_in_place(u.as_mut());
        let mut dyp = Mat::<T>::from_fn(n, 1, |k, _| ft[(k, 0)] - u[(k, 0)]);
        self.r.solve_upper_triangular_in_place(dyp.as_mut());
        let mut dr = Mat::<T>::from_fn(m, 1, |i, _| if i < n { u[(i, 0)] } else { ft[(i, 0)] });
        apply_q(self, &mut dr, false);
        let mut dy = Col::<T>::zeros(n);
        for k in 0..n {
            dy[self.cols[k]] = dyp[(k, 0)];
        }
        (Col::from_fn(m, |i| dr[(i, 0)]), dy)
    }
}

/// A full-rank thin SVD `A = U Σ Vᵀ`.
pub(super) struct SvdParts<'a, T> {
    pub u: MatRef<'a, T>,
    pub s: ColRef<'a, T>,
    pub v: MatRef<'a, T>,
}

impl<T: LsqReal> Augmented<T> for SvdParts<'_, T> {
    fn solve(&self, f: &Col<T>, g: &Col<T>) -> (Col<T>, Col<T>) {
        let (m, n) = (f.nrows(), g.nrows());
        // δy = V Σ⁻¹ (Uᵀf − Σ⁻¹ Vᵀg),  δr = f − U (Uᵀf − Σ⁻¹ Vᵀg).
        let t = Col::<T>::from_fn(n, |k| {
            let (mut utf, mut vtg) = (T::zero_impl(), T::zero_impl());
            for i in 0..m {
                utf += self.u[(i, k)] * f[i];
            }
            for j in 0..n {
                vtg += self.v[(j, k)] * g[j];
            }
            utf - vtg / self.s[k]
        });
        let dy = Col::from_fn(n, |j| {
            let mut acc = T::zero_impl();
            for k in 0..n {
                acc += self.v[(j, k)] * (t[k] / self.s[k]);
            }
            acc
        });
        let dr = Col::from_fn(m, |i| {
            let mut acc = f[i];
            for k in 0..n {
                acc -= self.u[(i, k)] * t[k];
            }
            acc
        });
        (dr, dy)
    }
}

/// Refines `y` in place, for at most `steps` steps; stops early once a correction no longer
/// shrinks or no longer changes `y` at working precision.
pub(super) fn refine<T: LsqReal>(
    a: MatRef<'_, T>,
    b: ColRef<'_, T>,
    solver: &impl Augmented<T>,
    y: &mut Col<T>,
    steps: usize,
) {
    let (m, n) = (a.nrows(), a.ncols());
    let residual = |y: &Col<T>, r: Option<&Col<T>>| -> Col<T> {
        Col::from_fn(m, |i| {
            let mut acc = Compensated::new();
            acc.add(b[i]);
            if let Some(r) = r {
                acc.add(-r[i]);
            }
            for j in 0..n {
                acc.add_product(-a[(i, j)], y[j]);
            }
            acc.value()
        })
    };
    let mut r = residual(y, None);
    let mut previous: Option<T> = None;
    for _ in 0..steps {
        let f = residual(y, Some(&r));
        let g = Col::<T>::from_fn(n, |j| {
            let mut acc = Compensated::new();
            for i in 0..m {
                acc.add_product(-a[(i, j)], r[i]);
            }
            acc.value()
        });
        let (dr, dy) = solver.solve(&f, &g);
        // Convergence is linear with rate about κ·ε: a correction that is not clearly smaller than
        // the previous one means the iteration has reached its limit (or cannot converge).
        let size = (0..n).fold(T::zero_impl(), |s, k| {
            let v = dy[k].abs();
            if v > s { v } else { s }
        });
        if !size.is_finite() || previous.is_some_and(|p| size > p * T::from_f64(0.5)) {
            break;
        }
        previous = Some(size);
        let mut changed = false;
        for j in 0..n {
            let new = y[j] + dy[j];
            changed |= new != y[j];
            y[j] = new;
        }
        for i in 0..m {
            r[i] += dr[i];
        }
        if !changed {
            break;
        }
    }
}
