//! Streaming pre-processing: closed forms, sort-based references, NaN hold, lanes = scalars.
use crate::common::same_bits;
use proptest::prelude::*;
use rootfuse_attitude::preprocess::{Hampel, LowPass, MovingMean, MovingMedian};
use rootfuse_eval::spectrum;
use rootfuse_lane::Lane;

fn sorted_median(w: &[f64]) -> f64 {
    let mut v = w.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The reference window at step `i`: the last `w` samples, the first sample repeated before
/// the start (the documented fill).
fn window(xs: &[f64], i: usize, w: usize) -> Vec<f64> {
    (0..w).map(|k| xs[(i + k + 1).saturating_sub(w)]).collect()
}

#[test]
fn low_pass_step_response_is_the_closed_form() {
    let a = 0.2;
    let mut lp = LowPass::<f64>::new(a);
    assert_eq!(lp.update(0.0), 0.0);
    for n in 1..50 {
        let y = lp.update(1.0);
        let exact = 1.0 - (1.0f64 - a).powi(n);
        assert!((y - exact).abs() < 1e-14, "n = {n}: {y} vs {exact}");
    }
    let lp = LowPass::<f64>::from_time_constant(0.1, 0.01);
    // The exact discretisation 1 − exp(−dt/τ), not the first-order dt/(τ + dt).
    assert!((lp.update_copy_a() + (-0.1f64).exp_m1()).abs() < 1e-15);
}

trait LowPassA {
    fn update_copy_a(self) -> f64;
}
impl LowPassA for LowPass<f64> {
    /// The factor `a` read back as the response to a unit step from 0.
    fn update_copy_a(mut self) -> f64 {
        self.update(0.0);
        self.update(1.0)
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn windows_match_their_references(xs in prop::collection::vec(-100.0..100.0f64, 1..60)) {
        let mut mean = MovingMean::<f64, 4>::new();
        let mut med = MovingMedian::<f64, 5>::new();
        let mut hampel = Hampel::<f64, 7>::new(3.0);
        for i in 0..xs.len() {
            let w4 = window(&xs, i, 4);
            let m = mean.update(xs[i]);
            prop_assert!((m - w4.iter().sum::<f64>() / 4.0).abs() < 1e-12);
            prop_assert_eq!(med.update(xs[i]), sorted_median(&window(&xs, i, 5)));
            let w7 = window(&xs, i, 7);
            let m7 = sorted_median(&w7);
            let mad = sorted_median(&w7.iter().map(|v| (v - m7).abs()).collect::<Vec<_>>());
            let want = if (xs[i] - m7).abs() > 3.0 * 1.4826 * mad { m7 } else { xs[i] };
            prop_assert_eq!(hampel.update(xs[i]), want);
        }
    }

    /// A NaN or ±∞ sample is replaced by the last finite input and counted: outputs equal a run
    /// fed that value instead.
    #[test]
    fn non_finite_samples_are_held_and_counted(xs in prop::collection::vec(-10.0..10.0f64, 12..40), at in 1usize..11,
                                               bad in prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY])) {
        let (mut med, mut med_ref) = (MovingMedian::<f64, 5>::new(), MovingMedian::<f64, 5>::new());
        let (mut lp, mut lp_ref) = (LowPass::<f64>::new(0.3), LowPass::<f64>::new(0.3));
        let (mut h, mut h_ref) = (Hampel::<f64, 5>::new(3.0), Hampel::<f64, 5>::new(3.0));
        for (i, &x) in xs.iter().enumerate() {
            let (input, held) = if i == at { (bad, xs[i - 1]) } else { (x, x) };
            prop_assert_eq!(med.update(input), med_ref.update(held));
            prop_assert_eq!(lp.update(input), lp_ref.update(held));
            prop_assert_eq!(h.update(input), h_ref.update(held));
        }
        prop_assert_eq!((med.rejected()[0], lp.rejected()[0], h.rejected()[0]), (1, 1, 1));
        prop_assert_eq!(med_ref.rejected()[0], 0);
    }

    /// Eight signals in f32x8 lanes equal eight scalar runs bit for bit, NaN in single lanes.
    #[test]
    fn lanes_equal_scalar_runs(xs in prop::array::uniform8(prop::collection::vec(prop_oneof![9 => -50.0..50.0f32, 1 => Just(f32::NAN)], 30))) {
        type V = wide::f32x8;
        let (mut lp, mut mean, mut med, mut hampel) =
            (LowPass::<V>::new(0.25), MovingMean::<V, 4>::new(), MovingMedian::<V, 5>::new(), Hampel::<V, 7>::new(2.5));
        let mut scalar: Vec<_> = (0..8)
            .map(|_| (LowPass::<f32>::new(0.25), MovingMean::<f32, 4>::new(), MovingMedian::<f32, 5>::new(), Hampel::<f32, 7>::new(2.5)))
            .collect();
        for k in 0..30 {
            let x = V::from_fn(|i| xs[i][k]);
            let out = [lp.update(x), mean.update(x), med.update(x), hampel.update(x)];
            for (i, s) in scalar.iter_mut().enumerate() {
                let v = xs[i][k];
                let want = [s.0.update(v), s.1.update(v), s.2.update(v), s.3.update(v)];
                for (o, w) in out.iter().zip(want) {
                    prop_assert!(same_bits(o.extract(i), w));
                }
            }
        }
        for i in 0..8 {
            prop_assert_eq!(hampel.replaced()[i], scalar[i].3.replaced()[0]);
            prop_assert_eq!(med.rejected()[i], scalar[i].2.rejected()[0]);
        }
    }
}

#[test]
fn spectrum_finds_a_sine() {
    let rate = 100.0;
    let signal: Vec<f64> = (0..200)
        .map(|k| 0.5 + 2.0 * (2.0 * std::f64::consts::PI * 10.0 * k as f64 / rate).sin())
        .collect();
    let s = spectrum(&signal, rate);
    assert_eq!(s.len(), 101);
    let (f, a) = s
        .iter()
        .copied()
        .fold((0.0, 0.0), |best, p| if p.1 > best.1 { p } else { best });
    assert!(
        (f - 10.0).abs() < 1e-12 && (a - 2.0).abs() < 1e-9,
        "peak {a} at {f} Hz"
    );
    assert!((s[0].1 - 0.5).abs() < 1e-12, "mean {}", s[0].1);
    assert!(spectrum(&[1.0], rate).is_empty());
}
