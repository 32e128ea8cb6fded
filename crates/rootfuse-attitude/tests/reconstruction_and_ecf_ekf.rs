//! `complementary-reconstruction` and `ecf-ekf` (patent methods): the measured comparisons
//! of docs/accuracy.md pinned, and method-specific checks.
//!
//! Simulated numbers: f64, 100 Hz, 60 s, seeds 1..=4 averaged, roll/pitch/yaw RMSE in
//! degrees from 2 s on (`metrics::euler_rmse`), the same set-up as
//! `examples/seed_001_004.rs`. The simulator is deterministic, so the pins are tight (5 %).
use rootfuse_attitude::filters::{ComplementaryReconstruction, ComplementaryReconstructionParams};
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{ImuSample, OrientationFilter, Quat, Vec3};
use rootfuse_eval::metrics::euler_rmse;
use rootfuse_eval::sim;

const G: f64 = 9.81;

fn earth_field() -> Vec3<f64> {
    let dip = 64f64.to_radians();
    Vec3::new(0.0, dip.cos(), -dip.sin()) * 50.0
}

/// Mean roll/pitch/yaw RMSE (degrees) of `name` with `overrides` over seeds 1..=4.
fn rpy(scenario: &str, name: &str, overrides: &[&str], dof: u8) -> [f64; 3] {
    let mut spec = FilterSpec::new(name).unwrap();
    spec.set_dof(crate::common::dof(dof)).unwrap();
    for o in overrides {
        spec.set(o).unwrap();
    }
    let mut mean = [0.0; 3];
    for seed in 1..=4 {
        let rec = sim::scenario(scenario, seed, 60.0, 100.0).unwrap();
        let est = rec.estimate(&mut spec.build::<f64>());
        for (m, x) in mean.iter_mut().zip(euler_rmse(&rec, &est, 2.0, dof == 6)) {
            *m += x / 4.0;
        }
    }
    mean
}

/// `got` within 5 % of the measured `want`, per axis.
fn pin(what: &str, got: [f64; 3], want: [f64; 3]) {
    for (axis, (g, w)) in ["roll", "pitch", "yaw"].iter().zip(got.iter().zip(want)) {
        assert!(
            (g - w).abs() <= 0.05 * w,
            "{what} {axis}: {g:.4}° (measured {w:.3}°)"
        );
    }
}

/// The ECF-EKF claim (static roll/pitch/yaw error 71 %/74 %/66 % below a plain EKF) is not
/// reproduced: on the static preset, 9D, `ecf-ekf` is 13 % lower in roll, equal in pitch
/// and 15 % higher in yaw than our `ekf`; both are within 0.25° (tilt) and 1.5° (yaw) of the
/// truth.
#[test]
fn ecf_ekf_static_against_ekf() {
    let ecf = rpy("static", "ecf-ekf", &[], 9);
    let ekf = rpy("static", "ekf", &[], 9);
    pin("ecf-ekf static 9D", ecf, [0.181, 0.208, 1.423]);
    pin("ekf static 9D", ekf, [0.208, 0.208, 1.240]);
    assert!(ecf[0] < 0.95 * ekf[0], "roll {ecf:?} vs {ekf:?}");
    assert!(
        (ecf[1] / ekf[1] - 1.0).abs() < 0.05,
        "pitch {ecf:?} vs {ekf:?}"
    );
    assert!(ecf[2] > 1.05 * ekf[2], "yaw {ecf:?} vs {ekf:?}");
    assert!(ecf[0] < 0.25 && ecf[1] < 0.25 && ecf[2] < 1.5, "{ecf:?}");
}

/// In motion: `ecf-ekf` beats `ekf` under linear acceleration (translation: roll 1.43° vs
/// 3.98°), trails it in slow rotation, and the source's 10-sample window lags: 7× the roll
/// error of the default window on fast rotation at 100 Hz.
#[test]
fn ecf_ekf_dynamic_against_ekf() {
    let ecf = rpy("translation", "ecf-ekf", &[], 9);
    let ekf = rpy("translation", "ekf", &[], 9);
    pin("ecf-ekf translation 9D", ecf, [1.434, 0.783, 3.063]);
    pin("ekf translation 9D", ekf, [3.978, 1.470, 5.757]);
    assert!(ecf.iter().zip(&ekf).all(|(a, b)| a < &(0.6 * b)));

    let slow_ecf = rpy("slow-rotation", "ecf-ekf", &[], 9);
    let slow_ekf = rpy("slow-rotation", "ekf", &[], 9);
    pin("ecf-ekf slow 9D", slow_ecf, [0.478, 0.271, 1.912]);
    assert!(slow_ecf.iter().zip(&slow_ekf).all(|(a, b)| a > b));

    let fast = rpy("fast-rotation", "ecf-ekf", &[], 9);
    let fast_w10 = rpy("fast-rotation", "ecf-ekf", &["window=10"], 9);
    pin("ecf-ekf fast 9D", fast, [1.214, 0.769, 1.872]);
    pin("ecf-ekf window=10 fast 9D", fast_w10, [8.412, 3.863, 8.555]);
    assert!(fast_w10[0] > 5.0 * fast[0]);
}

/// 6D with gravity only: both filters keep roll and pitch within 0.6° on slow rotation; the
/// heading is gyro-borne (`ecf-ekf` drifts like gyro integration, 9.6° vs 10.9°; the
/// still-period bias keeps `complementary-reconstruction` at 0.36°).
#[test]
fn six_d_gravity_only() {
    let ecf = rpy("slow-rotation", "ecf-ekf", &[], 6);
    let cr = rpy("slow-rotation", "complementary-reconstruction", &[], 6);
    pin("ecf-ekf slow 6D", ecf, [0.541, 0.297, 9.649]);
    pin("reconstruction slow 6D", cr, [0.285, 0.185, 0.362]);
}

/// Reconstruction vs gyro-only and a fixed-α blend: far better than gyro-only everywhere, but
/// the adaptive α is worse than a fixed α = 0.99 (translation roll 9.27° vs 4.64°; fast
/// rotation 0.71° vs 0.44°).
#[test]
fn reconstruction_against_gyro_and_fixed_alpha() {
    let name = "complementary-reconstruction";
    let cr = rpy("slow-rotation", name, &[], 9);
    let gyro = rpy("slow-rotation", "gyro", &[], 9);
    pin("reconstruction slow 9D", cr, [0.284, 0.185, 1.469]);
    assert!(
        cr[0] < 0.1 * gyro[0] && cr[1] < 0.1 * gyro[1],
        "{cr:?} vs {gyro:?}"
    );

    let adaptive = rpy("translation", name, &[], 9);
    let fixed = rpy("translation", name, &["alpha_fixed=0.99"], 9);
    pin(
        "reconstruction translation 9D",
        adaptive,
        [9.272, 4.639, 12.642],
    );
    pin(
        "reconstruction α=0.99 translation 9D",
        fixed,
        [4.636, 2.159, 6.831],
    );
    assert!(adaptive.iter().zip(&fixed).all(|(a, f)| *a > 1.5 * f));

    let fast = rpy("fast-rotation", name, &[], 9);
    let fast_fixed = rpy("fast-rotation", name, &["alpha_fixed=0.99"], 9);
    pin("reconstruction fast 9D", fast, [0.707, 0.414, 1.613]);
    assert!(fast[0] > 1.3 * fast_fixed[0]);
}

/// The coning correction (trapezoid + `T²/12·ω_{k−1} × ω_k`) against `Φ = ω·T` on fast
/// rotation: roll 0.71° vs 1.19°.
#[test]
fn reconstruction_coning_on_fast_rotation() {
    let name = "complementary-reconstruction";
    let on = rpy("fast-rotation", name, &[], 9);
    let off = rpy("fast-rotation", name, &["coning=0"], 9);
    pin("coning=0 fast 9D", off, [1.187, 0.627, 1.919]);
    assert!(
        on[0] < 0.7 * off[0] && on[1] < 0.7 * off[1],
        "{on:?} vs {off:?}"
    );
}

fn reconstruction(overrides: &[&str]) -> ComplementaryReconstruction<f64> {
    let mut p = ComplementaryReconstructionParams::default();
    for o in overrides {
        rootfuse_attitude::filters::Params::apply(&mut p, o).unwrap();
    }
    ComplementaryReconstruction::new(&p)
}

/// α → 0 at rest and α → 1 in motion (long-rest preset, seed 1, 9D): after the still period,
/// α stays below 0.6 during the final rest and above 0.95 wherever the rate exceeds 0.3 rad/s.
#[test]
fn alpha_follows_motion() {
    let rec = sim::scenario("long-rest", 1, 60.0, 100.0).unwrap();
    let mut f = reconstruction(&[]);
    let (mut rest_max, mut moving_min) = (0.0f64, 1.0f64);
    for i in 0..rec.len() {
        let s = rec.sample(i);
        f.update(&ImuSample::new(s.gyr, s.acc, s.mag), rec.dt(i));
        let t = rec.t[i];
        if t > 0.25 * 60.0 + 1.0 {
            rest_max = rest_max.max(f.alpha());
        } else if t > 1.0 && s.gyr.norm() > 0.3 {
            moving_min = moving_min.min(f.alpha());
        }
    }
    assert!(rest_max < 0.6, "α at rest up to {rest_max}");
    assert!(moving_min > 0.95, "α in motion down to {moving_min}");
}

/// A noiseless turn about up at 1 rad/s for 15 s: the gyro quaternion crosses into `w < 0`
/// while the observation (Shepperd, `w ≥ 0`) stays put, so the two are antipodal
/// representatives; with α = 0.5 an unaligned blend would cancel. The estimate stays within
/// 1e-6° of the truth.
#[test]
fn reconstruction_blend_is_hemisphere_aligned() {
    let mut f = reconstruction(&["alpha_fixed=0.5", "still_s=0"]);
    let w = Vec3::new(0.0, 0.0, 1.0);
    let (mut q, mut worst, mut min_w) = (Quat::<f64>::identity(), 0.0f64, 1.0f64);
    let level = ImuSample::new(w, Vec3::new(0.0, 0.0, G), earth_field());
    // The first sample only sets the attitude (a negligible step).
    f.update(&level, 1e-12);
    for _ in 0..1500 {
        q = (q * Quat::from_rotation_vector(w * 0.01)).normalize();
        let s = ImuSample::new(
            w,
            q.rotate_inverse(Vec3::new(0.0, 0.0, G)),
            q.rotate_inverse(earth_field()),
        );
        f.update(&s, 0.01);
        worst = worst.max(f.quat().angle_to(q).to_degrees());
        min_w = min_w.min(f.quat().w);
    }
    assert!(
        min_w < -0.9,
        "the estimate never changed hemisphere ({min_w})"
    );
    assert!(worst < 1e-6, "{worst}°");
}

/// Coning: the body-axis cone `q(t) = qz(Ωt) ⊗ qx(β) ⊗ qz(−Ωt)` (β = 0.2 rad, Ω = 2π rad/s)
/// has the closed-form rate `ω = Ω·(−sin β·sin Ωt, sin β·cos Ωt, cos β − 1)`. Gyro only
/// (α = 1), 20 s, worst error against the closed form. Measured: at 100 Hz, 0.0935° with the
/// coning correction (a steady drift: the trapezoid increments of point rate samples are off
/// by `O(T³)`; with exact increments the same formula gives 4e-6°) and 0.717° with
/// `Φ = ω·T` (the half-sample lead of the right-end rate); at 200 Hz the corrected error is
/// a quarter (second order).
#[test]
fn coning_correction_against_closed_form() {
    let (beta, omega) = (0.2f64, 2.0 * std::f64::consts::PI);
    let truth = |t: f64| {
        Quat::from_heading(omega * t)
            * Quat::new((beta / 2.0).cos(), (beta / 2.0).sin(), 0.0, 0.0)
            * Quat::from_heading(-omega * t)
    };
    let rate = |t: f64| {
        Vec3::new(
            -beta.sin() * (omega * t).sin(),
            beta.sin() * (omega * t).cos(),
            beta.cos() - 1.0,
        ) * omega
    };
    let worst_error = |coning: &str, h: f64| {
        let mut f = reconstruction(&["alpha_fixed=1", "still_s=0", coning]);
        let sample = |t: f64| {
            let q = truth(t);
            ImuSample::new(
                rate(t),
                q.rotate_inverse(Vec3::new(0.0, 0.0, G)),
                q.rotate_inverse(earth_field()),
            )
        };
        // The first sample only sets the attitude (a negligible step).
        f.update(&sample(0.0), 1e-12);
        let mut worst = 0.0f64;
        for k in 1..=(20.0 / h).round() as usize {
            let t = k as f64 * h;
            f.update(&sample(t), h);
            worst = worst.max(f.quat().angle_to(truth(t)).to_degrees());
        }
        worst
    };
    let (on, off) = (worst_error("coning=1", 0.01), worst_error("coning=0", 0.01));
    assert!((on - 0.0935).abs() < 0.005, "with coning correction {on}°");
    assert!((off - 0.717).abs() < 0.03, "without {off}°");
    let on_200hz = worst_error("coning=1", 0.005);
    assert!(
        (on_200hz / on - 0.25).abs() < 0.02,
        "{on_200hz}° at 200 Hz vs {on}°"
    );
}
