//! Every registered filter's update on arbitrary samples and time steps.

use crate::Bytes;
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::{Dof, ImuSample, Lane, OrientationFilter, Vec3};

/// Most steps one input runs (keeps every input fast).
const MAX_STEPS: usize = 400;

/// Chooses a registered filter from the input: byte 0 picks it from [`FilterKind::ALL`], byte
/// 1 the dimension (6D/9D) and, when its bit 2 is set, a parameter (byte 2) that is set to the
/// end of its accepted range (byte 3).
pub(crate) fn spec_from(input: &mut Bytes) -> FilterSpec {
    let kind = FilterKind::ALL[usize::from(input.u8()) % FilterKind::ALL.len()];
    let flags = input.u8();
    // Unreachable: the name comes from the registry itself, and 6 and 9 are the two values
    // every `dof` parameter accepts.
    let mut spec = FilterSpec::new(kind.name()).expect("unreachable: a registered name");
    spec.set_dof(if flags & 2 != 0 { Dof::Nine } else { Dof::Six })
        .expect("unreachable: 6 and 9 are valid dimensions");
    let which = input.u8();
    let end = input.u8();
    let params = kind.params();
    if flags & 4 != 0 && !params.is_empty() {
        let p = params[usize::from(which) % params.len()];
        let value = if end & 1 == 0 { p.min } else { p.max };
        // The ends are inclusive, so the override must be accepted; a rejection is an
        // invariant failure, reported by panicking as every check of this harness is.
        spec.set(&format!("{}={value:?}", p.name))
            .unwrap_or_else(|e| panic!("{}: end of range rejected: {e}", kind.name()));
    }
    spec
}

/// Reads one sample (9 values) and a time step.
pub(crate) fn sample_from(input: &mut Bytes, single: bool) -> (ImuSample<f64>, f64) {
    let mut v = [0.0; 9];
    for x in &mut v {
        *x = input.value(single);
    }
    let s = ImuSample::new(
        Vec3::new(v[0], v[1], v[2]),
        Vec3::new(v[3], v[4], v[5]),
        Vec3::new(v[6], v[7], v[8]),
    );
    (s, input.dt(single))
}

/// Fuzz target `filter_update`: one registered filter (chosen by the first byte) in `f32` or
/// `f64`, fed arbitrary samples and time steps.
///
/// Invariants after every update: no panic; the quaternion is finite with
/// `|‖q‖ − 1| ≤ 1e-5` (`f32`) or `1e-12` (`f64`); the bias is finite; a sample whose `dt` is
/// not in `(0, max_dt]` is counted in `dt`, otherwise one whose gyroscope is not finite or
/// above `max_gyr` is counted in `gyr`, and either leaves quaternion and bias bit for bit as
/// they were; a usable step with a non-finite, zero or clearly too large (beyond `max_acc`)
/// accelerometer counts one `acc` rejection, and in 9D one with a non-finite, zero or clearly
/// too large (beyond `max_mag`) magnetometer one `mag` rejection.
pub fn filter_update(data: &[u8]) {
    let mut input = Bytes::new(data);
    let spec = spec_from(&mut input);
    if input.u8() & 1 == 0 {
        run::<f32>(&spec, &mut input, true, 1e-5);
    } else {
        run::<f64>(&spec, &mut input, false, 1e-12);
    }
}

/// Unusable by the screening rule: not finite, zero, or beyond `limit` (by a relative margin
/// of 1e-4, so that the lane type's rounding of the norm cannot decide the case).
fn unusable(v: Vec3<f64>, limit: f64) -> bool {
    !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite())
        || (v.x == 0.0 && v.y == 0.0 && v.z == 0.0)
        || (v.x * v.x + v.y * v.y + v.z * v.z).sqrt() > limit * (1.0 + 1e-4)
}

fn same_bits<S: Lane<Scalar = S> + Into<f64>>(a: &[S], b: &[S]) -> bool {
    a.iter()
        .zip(b)
        .all(|(x, y)| Into::<f64>::into(*x).to_bits() == Into::<f64>::into(*y).to_bits())
}

fn run<S: Lane<Scalar = S, Mask = bool> + Into<f64>>(
    spec: &FilterSpec,
    input: &mut Bytes,
    single: bool,
    tol: f64,
) {
    let name = spec.kind().name();
    let nine_d = spec.uses_magnetometer();
    let limits = spec.screen_limits();
    let mut f = spec.build::<S>();
    let c = |v: Vec3<f64>| Vec3::<S>::from_f64([v.x, v.y, v.z]);
    for step in 0..MAX_STEPS {
        if input.is_empty() {
            break;
        }
        let (s64, dt64) = sample_from(input, single);
        let s = ImuSample::new(c(s64.gyr), c(s64.acc), c(s64.mag));
        let dt = S::from_f64(dt64);
        let (q0, b0, r0) = (f.quat(), f.bias(), *f.rejections());
        f.update(&s, dt);
        let (q, b, r) = (f.quat(), f.bias(), f.rejections());

        let qa = q.to_array().map(Into::<f64>::into);
        let norm = qa.iter().map(|c| c * c).sum::<f64>().sqrt();
        assert!(
            qa.iter().all(|c| c.is_finite()) && (norm - 1.0).abs() <= tol,
            "{name} step {step}: quaternion {qa:?} (norm {norm}) after {s64:?}, dt {dt64}"
        );
        let ba = [b.x, b.y, b.z].map(Into::<f64>::into);
        assert!(
            ba.iter().all(|c| c.is_finite()),
            "{name} step {step}: bias {ba:?}"
        );

        // The same predicates as the documented screening rule, evaluated in the lane type.
        let dt_ok = dt64 > 0.0 && dt.simd_le(S::from_f64(limits.max_dt));
        let g2 = s.gyr.norm_squared();
        let gyr_ok = g2.simd_le(S::from_f64(limits.max_gyr * limits.max_gyr));
        let d = |after: u64, before: u64| after - before;
        assert_eq!(
            d(r.dt.as_ref()[0], r0.dt.as_ref()[0]),
            u64::from(!dt_ok),
            "{name} step {step}: dt count, dt {dt64}"
        );
        assert_eq!(
            d(r.gyr.as_ref()[0], r0.gyr.as_ref()[0]),
            u64::from(dt_ok && !gyr_ok),
            "{name} step {step}: gyro count for {:?}",
            s64.gyr
        );
        if !(dt_ok && gyr_ok) {
            assert!(
                same_bits(&q.to_array(), &q0.to_array())
                    && same_bits(&[b.x, b.y, b.z], &[b0.x, b0.y, b0.z]),
                "{name} step {step}: a skipped sample moved the state"
            );
            assert_eq!(
                r.acc.as_ref()[0],
                r0.acc.as_ref()[0],
                "{name}: skipped sample counted as acc"
            );
            assert_eq!(
                r.mag.as_ref()[0],
                r0.mag.as_ref()[0],
                "{name}: skipped sample counted as mag"
            );
        } else {
            if unusable(s64.acc, limits.max_acc) {
                assert_eq!(
                    d(r.acc.as_ref()[0], r0.acc.as_ref()[0]),
                    1,
                    "{name} step {step}: acc {:?} not counted",
                    s64.acc
                );
            }
            if nine_d && unusable(s64.mag, limits.max_mag) {
                assert_eq!(
                    d(r.mag.as_ref()[0], r0.mag.as_ref()[0]),
                    1,
                    "{name} step {step}: mag {:?} not counted",
                    s64.mag
                );
            }
        }
        if !nine_d {
            assert_eq!(
                r.mag.as_ref()[0],
                0,
                "{name}: a 6D filter counted a magnetometer rejection"
            );
        }
    }
}
