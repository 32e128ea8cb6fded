//! LS quaternion fusion (`lsq-fusion`): the denoiser against closed forms, drift
//! recovery, no vertical windup, and the measured comparison with `complementary`
//! (docs/accuracy.md has the tables).
use crate::common::broad_dir;
use nalgebra::Matrix3;
use rootfuse_attitude::filters::{LsqFusion, LsqFusionParams, PolyDenoiser};
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{ImuSample, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_eval::metrics::{Alignment, evaluate};
use rootfuse_eval::sim::{self, Segment, Trajectory};
use rootfuse_io::read_csv;

/// Deterministic standard normal draws (xorshift64* and Box–Muller).
struct Normal(u64);
impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// Output variance over input variance of the discounted LS fit at the current point, from
/// the sums `M = Σ θ^j h_j h_jᵀ`, `M₂ = Σ θ^{2j} h_j h_jᵀ`, `h_j = [1, −j r, (j r)²][..n]`,
/// `θ = 1/(1 + r)` (the series converge geometrically; 20 000 terms are exact in f64).
fn variance_factor(n: usize, r: f64) -> f64 {
    let theta = 1.0 / (1.0 + r);
    let (mut m, mut m2) = (Matrix3::<f64>::zeros(), Matrix3::<f64>::zeros());
    for j in 0..20_000 {
        let s = -(j as f64) * r;
        let h = nalgebra::Vector3::new(1.0, s, s * s);
        let w = theta.powi(j);
        m += h * h.transpose() * w;
        m2 += h * h.transpose() * (w * w);
    }
    let m = m.view((0, 0), (n, n)).into_owned();
    let m2 = m2.view((0, 0), (n, n)).into_owned();
    let mi = m.try_inverse().unwrap();
    (&mi * m2 * &mi)[(0, 0)]
}

#[test]
fn variance_factor_matches_browns_closed_form() {
    for r in [0.01, 0.1, 0.5] {
        let t: f64 = 1.0 / (1.0 + r);
        let brown = (1.0 - t) * (1.0 + 4.0 * t + 5.0 * t * t) / (1.0 + t).powi(3);
        assert!((variance_factor(2, r) - brown).abs() < 1e-9 * brown);
        assert!((variance_factor(1, r) - (1.0 - t) / (1.0 + t)).abs() < 1e-12);
    }
}

/// A polynomial of degree < N is reproduced exactly once the prior is forgotten.
#[test]
fn denoiser_reproduces_polynomials() {
    let dt = 0.01;
    let mut quad = PolyDenoiser::<f64, 3>::new(0.05, 0.01);
    let mut line = PolyDenoiser::<f64, 2>::new(0.05, 0.01);
    let mut quad32 = PolyDenoiser::<f32, 3>::new(0.05, 0.01);
    for k in 0..400 {
        let t = k as f64 * dt;
        let y = 0.3 + 2.0 * t - 1.5 * t * t;
        let l = -0.7 + 4.0 * t;
        let (a, b, c) = (
            quad.update(y, dt, true),
            line.update(l, dt, true),
            quad32.update(y as f32, dt as f32, true),
        );
        if k >= 300 {
            assert!((a - y).abs() < 1e-9, "quadratic at {t}: {a} vs {y}");
            assert!((b - l).abs() < 1e-9, "line at {t}: {b} vs {l}");
            assert!(
                (c as f64 - y).abs() < 2e-4,
                "f32 quadratic at {t}: {c} vs {y}"
            );
        }
    }
    // The slope is the derivative in units of τ: 2 − 3t per second, times τ = 0.05 s.
    let t = 399.0 * dt;
    assert!((quad.coefficients()[1] - (2.0 - 3.0 * t) * 0.05).abs() < 1e-8);
}

/// White noise: the output variance is the closed form's factor of the input's, measured
/// within 3 % over 400 000 samples. At τ = 10·dt the local quadratic keeps 0.182 of the
/// variance (the local line 0.115, Brown).
#[test]
fn denoiser_reduces_white_noise_by_the_closed_form() {
    let (dt, tau) = (0.01, 0.1);
    let factor = variance_factor(3, dt / tau);
    assert!((0.180..0.184).contains(&factor), "factor {factor}");
    assert!((variance_factor(2, dt / tau) - 0.1146).abs() < 1e-3);
    let mut d = PolyDenoiser::<f64, 3>::new(tau, 1.0);
    let mut rng = Normal(0x9E37_79B9_7F4A_7C15);
    let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0.0);
    for k in 0..400_000 {
        let y = d.update(rng.next(), dt, true);
        if k >= 1000 {
            sum += y;
            sum2 += y * y;
            n += 1.0;
        }
    }
    let var = sum2 / n - (sum / n).powi(2);
    assert!(
        (var / factor - 1.0).abs() < 0.03,
        "measured {var}, closed form {factor}"
    );
}

/// A still, level sensor in 6D with a constant gyro bias: the horizontal components are
/// recovered; the vertical one is unobservable and the estimator neither learns it nor winds
/// up (its variance stays at the bound `drift_max²`, its estimate near 0, every eigenvalue of
/// the covariance at most the bound); the quaternion stays unit.
#[test]
fn horizontal_drift_is_recovered_and_vertical_does_not_wind_up() {
    let bias = Vec3::new(0.004, -0.003, 0.01);
    let p = LsqFusionParams {
        dof: rootfuse_attitude::Dof::Six,
        ..Default::default()
    };
    let mut f = LsqFusion::<f64>::new(&p);
    let mut rng = Normal(7);
    let dt = 0.01;
    for k in 0..100 * 900 {
        let n = |r: &mut Normal, s: f64| Vec3::new(r.next(), r.next(), r.next()) * s;
        let gyr = bias + n(&mut rng, 0.005);
        let acc = Vec3::new(0.0, 0.0, 9.81) + n(&mut rng, 0.02);
        f.update(&ImuSample::six_d(gyr, acc), dt);
        if k % 1000 == 0 {
            assert!((f.quat().norm() - 1.0).abs() < 1e-9);
        }
    }
    let b = f.bias();
    assert!((b.x - bias.x).abs() < 3e-4, "x: {}", b.x);
    assert!((b.y - bias.y).abs() < 3e-4, "y: {}", b.y);
    assert!(b.z.abs() < 1e-3, "vertical estimate moved: {}", b.z);
    let p_max = p.drift_max * p.drift_max;
    let cov = f.drift().covariance();
    let c = Matrix3::from_fn(|i, j| cov.m[i][j]);
    let eig = c.symmetric_eigenvalues();
    assert!(eig.max() <= p_max * (1.0 + 1e-9), "eigenvalues {eig:?}");
    assert!(
        cov.m[2][2] > 0.9 * p_max,
        "vertical variance {}",
        cov.m[2][2]
    );
    assert!(cov.m[0][0] < 0.01 * p_max && cov.m[1][1] < 0.01 * p_max);
}

/// The drift of the simulated slow rotation (bias N(0, 5 mrad/s) per axis plus a random walk)
/// is recovered in all three axes, 6D and 9D (rotation makes each body axis horizontal in
/// turn).
#[test]
fn drift_is_recovered_on_a_simulated_rotation() {
    let out = sim::scenario_simulation("slow-rotation", 1, 120.0, 100.0)
        .unwrap()
        .run()
        .unwrap();
    let rec = &out.recording;
    let truth = *out.gyro_bias.last().unwrap();
    for dof in [6u8, 9] {
        let p = LsqFusionParams {
            dof: crate::common::dof(dof),
            ..Default::default()
        };
        let mut f = LsqFusion::<f64>::new(&p);
        for i in 0..rec.len() {
            let s = rec.sample(i);
            f.update(&ImuSample::new(s.gyr, s.acc, s.mag), rec.dt(i));
        }
        let err = (f.bias() - truth).norm();
        eprintln!("{dof}D drift error {err:e} (truth {truth:?})");
        assert!(err < 1.5e-3, "{dof}D: drift error {err} rad/s");
    }
}

/// A turntable: the sensor tilted on a table turning about the vertical at 0.5, −1, 2, −0.3,
/// 1.5 rad/s, framed by rest.
fn turntable(seed: u64, d: f64, rate: f64) -> Recording {
    let mut s = sim::scenario_simulation("slow-rotation", seed, d, rate).unwrap();
    let q0 = Quat::from_euler_zyx(0.3 * seed as f64, 0.15, -0.25);
    let axis = q0.rotate_inverse(Vec3::new(0.0, 0.0, 1.0));
    let mut segs = vec![Segment::rest(0.1 * d)];
    for r in [0.5, -1.0, 2.0, -0.3, 1.5] {
        segs.push(Segment::rotate(0.16 * d, axis, r));
    }
    segs.push(Segment::rest(0.1 * d));
    s.trajectory = Trajectory::new(q0, segs).unwrap();
    s.run().unwrap().recording
}

fn mean_rmse(name: &str, dof: u8, recs: &[Recording]) -> f64 {
    let mut spec = FilterSpec::new(name).unwrap();
    spec.set_dof(crate::common::dof(dof)).unwrap();
    let align = if dof == 9 {
        Alignment::NineD
    } else {
        Alignment::SixD
    };
    recs.iter()
        .map(|r| {
            evaluate(r, &r.estimate(&mut spec.build::<f64>()), align)
                .unwrap()
                .total
        })
        .sum::<f64>()
        / recs.len() as f64
}

/// Mean total RMSE of `lsq-fusion` over `complementary` (seeds 1–3, 120 s at 100 Hz), pinned
/// within 0.03 + 3 %: the comparison goes both ways (see docs/accuracy.md).
#[test]
fn against_complementary_on_simulations() {
    #[rustfmt::skip]
    let pinned: [(&str, u8, f64); 8] = [
        ("slow-rotation", 9, 0.53), ("long-rest", 9, 0.59), ("translation", 9, 2.52), ("vibration", 9, 2.00),
        ("slow-rotation", 6, 0.16), ("long-rest", 6, 0.10), ("translation", 6, 3.27), ("turntable", 6, 0.98),
    ];
    let mut failures = Vec::new();
    for (name, dof, want) in pinned {
        let recs: Vec<Recording> = (1..=3)
            .map(|seed| {
                if name == "turntable" {
                    turntable(seed, 120.0, 100.0)
                } else {
                    sim::scenario(name, seed, 120.0, 100.0).unwrap()
                }
            })
            .collect();
        let ratio = mean_rmse("lsq-fusion", dof, &recs) / mean_rmse("complementary", dof, &recs);
        eprintln!("{name} {dof}D: ratio {ratio:.3} (pinned {want})");
        if (ratio - want).abs() > 0.03 + 0.03 * want {
            failures.push(format!("{name} {dof}D: {ratio:.3} vs {want}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The same ratio on the four BROAD trials, 9D and 6D.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn against_complementary_on_broad() {
    let Some(dir) = broad_dir() else { return };
    #[rustfmt::skip]
    let pinned: [(&str, [f64; 2]); 4] = [
        ("02_undisturbed_slow_rotation_B", [0.88, 0.78]),
        ("07_undisturbed_fast_rotation_B", [1.16, 1.23]),
        ("16_undisturbed_fast_translation_B", [0.79, 0.39]),
        ("29_disturbed_stationary_magnet_B", [1.77, 0.67]),
    ];
    let mut failures = Vec::new();
    for (trial, want) in pinned {
        let rec = [read_csv(dir.join(format!("{trial}.csv"))).unwrap()];
        for (k, dof) in [9u8, 6].into_iter().enumerate() {
            let ratio = mean_rmse("lsq-fusion", dof, &rec) / mean_rmse("complementary", dof, &rec);
            eprintln!("{trial} {dof}D: ratio {ratio:.3} (pinned {})", want[k]);
            if (ratio - want[k]).abs() > 0.03 + 0.03 * want[k] {
                failures.push(format!("{trial} {dof}D: {ratio:.3} vs {}", want[k]));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// `Potter::predict`: `x ← F x`, `P ← F P Fᵀ/λ` against the dense product; a bad `λ` or `F`
/// leaves the lane as it was; refused with covariance bounds.
#[test]
fn potter_predict_is_the_transition() {
    use rootfuse_lane::{Mat, Vector};
    use rootfuse_lsq::rls::{Potter, RecursiveLeastSquares, RlsConfig, RlsError};
    let x0 = Vector::<f64, 2>::from_column([1.0, -2.0]);
    let p0 = Mat::from_rows([[2.0, 0.3], [0.3, 1.0]]);
    let mut rls = Potter::new(&x0, &p0, RlsConfig::new(1.0)).unwrap();
    let f = Mat::from_rows([[1.0, 0.5], [0.0, 1.0]]);
    assert!(rls.predict(&f, 0.8).unwrap());
    let want = (f * p0 * f.transpose()).scale(1.0 / 0.8);
    let got = rls.covariance();
    for i in 0..2 {
        for j in 0..2 {
            assert!((got.m[i][j] - want.m[i][j]).abs() < 1e-12);
        }
    }
    assert_eq!(rls.estimate().m, (f * x0).m);
    let before = (rls.estimate().m, rls.covariance().m);
    assert!(!rls.predict(&f, 1.5).unwrap());
    assert!(!rls.predict(&f, f64::NAN).unwrap());
    assert!(!rls.predict(&f.scale(f64::INFINITY), 0.9).unwrap());
    assert_eq!(before, (rls.estimate().m, rls.covariance().m));
    let mut bounded = Potter::new(&x0, &p0, RlsConfig::new(0.99).with_bounds(0.0, 10.0)).unwrap();
    assert_eq!(
        bounded.predict(&f, 1.0),
        Err(RlsError::TransitionWithBounds)
    );
}
