//! Unit quaternions of lanes and their kernels.
//!
//! Convention: `q = [w, x, y, z]`, Hamilton product, `v_earth = q ⊗ v_sensor ⊗ q*`.
//! Every function is branch-free over lanes: where a formula has a singular point (zero
//! rotation, gimbal lock, antipodal slerp) both sides are computed and selected per lane.

use crate::vec3::Vec3;
use core::ops::{Add, Mul, Neg, Sub};
use rootfuse_lane::{Lane, Mask, Mat};

/// A quaternion `w + x·i + y·j + z·k` (Hamilton). Orientations are unit quaternions rotating
/// sensor coordinates to earth coordinates; `q` and `-q` are the same orientation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quat<T> {
    /// Scalar part.
    pub w: T,
    /// `i` component.
    pub x: T,
    /// `j` component.
    pub y: T,
    /// `k` component.
    pub z: T,
}

impl<T: Lane> Default for Quat<T> {
    fn default() -> Self {
        Self::identity()
    }
}

/// Half-angle threshold below which the exponential and logarithm maps use their series.
/// The first dropped term is `θ⁶/46080` relative; below this it is under one ulp in f32.
const SERIES_LIMIT: f64 = 0.01;

/// Angle below which [`Quat::exp`] uses its series through `a¹⁰` (exact to f64 rounding).
const EXP_SERIES_LIMIT: f64 = 0.25;

impl<T: Lane> Quat<T> {
    /// From components `[w, x, y, z]`.
    #[inline]
    pub const fn new(w: T, x: T, y: T, z: T) -> Self {
        Self { w, x, y, z }
    }
    /// The identity rotation `[1, 0, 0, 0]`.
    #[inline]
    pub fn identity() -> Self {
        Self::new(T::one(), T::zero(), T::zero(), T::zero())
    }
    /// From `f64` components `[w, x, y, z]` (constants, test values), not normalised.
    #[inline]
    pub fn from_f64(q: [f64; 4]) -> Self {
        Self::new(
            T::from_f64(q[0]),
            T::from_f64(q[1]),
            T::from_f64(q[2]),
            T::from_f64(q[3]),
        )
    }
    /// From a scalar and a vector part.
    #[inline]
    pub fn from_parts(w: T, v: Vec3<T>) -> Self {
        Self::new(w, v.x, v.y, v.z)
    }
    /// The pure quaternion `[0, v]`.
    #[inline]
    pub fn pure(v: Vec3<T>) -> Self {
        Self::from_parts(T::zero(), v)
    }
    /// The vector part `[x, y, z]`.
    #[inline]
    pub fn vector(self) -> Vec3<T> {
        Vec3::new(self.x, self.y, self.z)
    }
    /// As an array `[w, x, y, z]`.
    #[inline]
    pub fn to_array(self) -> [T; 4] {
        [self.w, self.x, self.y, self.z]
    }
    /// From an array `[w, x, y, z]` (scalar first, as [`to_array`](Self::to_array) gives
    /// it), not normalised; also `Quat::from([w, x, y, z])`.
    ///
    /// ```
    /// use rootfuse_attitude::Quat;
    /// let q = Quat::from_array([1.0_f64, 0.0, 0.0, 0.0]);
    /// assert_eq!(q, Quat::identity());
    /// assert_eq!(<[f64; 4]>::from(q), [1.0, 0.0, 0.0, 0.0]);
    /// ```
    #[inline]
    pub fn from_array(q: [T; 4]) -> Self {
        Self::new(q[0], q[1], q[2], q[3])
    }
    /// The conjugate `[w, -x, -y, -z]` (the inverse rotation for a unit quaternion).
    #[inline]
    pub fn conj(self) -> Self {
        Self::new(self.w, -self.x, -self.y, -self.z)
    }
    /// Four-dimensional dot product.
    #[inline]
    pub fn dot(self, o: Self) -> T {
        self.w
            .mul_add(o.w, self.x.mul_add(o.x, self.y.mul_add(o.y, self.z * o.z)))
    }
    /// Squared norm.
    #[inline]
    pub fn norm_squared(self) -> T {
        self.dot(self)
    }
    /// Norm.
    #[inline]
    pub fn norm(self) -> T {
        self.norm_squared().sqrt()
    }
    /// Every component times `s`.
    #[inline]
    pub fn scale(self, s: T) -> Self {
        Self::new(self.w * s, self.x * s, self.y * s, self.z * s)
    }
    /// Unit quaternion and a per-lane mask of where that was possible.
    ///
    /// Lanes with a zero, tiny, NaN or infinite norm get the identity and a false mask bit.
    #[inline]
    pub fn try_normalize(self) -> (Self, T::Mask) {
        let n2 = self.norm_squared();
        let ok = n2.simd_gt(T::from_f64(1e-30)) & n2.is_finite();
        let inv = T::one() / n2.sqrt();
        (Self::select(ok, self.scale(inv), Self::identity()), ok)
    }
    /// Unit quaternion; the identity in lanes that cannot be normalised (see
    /// [`try_normalize`](Self::try_normalize)).
    #[inline]
    pub fn normalize(self) -> Self {
        self.try_normalize().0
    }
    /// `self / |self|` for a quaternion within rounding of unit length, such as a product of
    /// unit quaternions: one Newton step of `1/√n` from 1, `q·(3 − |q|²)/2`. For
    /// `|q|² = 1 + ε` the result's norm is `1 − 3ε²/8` (below `1e-13` from the few ulp a
    /// product leaves), so it is [`normalize`](Self::normalize) to rounding, with three
    /// multiply-adds on an update's dependency chain where a square root and a division
    /// would be. Far from unit length it is no normalisation: use `normalize`.
    ///
    /// ```
    /// use rootfuse_attitude::Quat;
    /// let a = Quat::<f64>::from_euler_zyx(0.3, -0.2, 0.1);
    /// let b = Quat::<f64>::from_euler_zyx(-1.0, 0.5, 2.0);
    /// let q = (a * b).renormalize();
    /// assert!((q.norm_squared() - 1.0).abs() < 1e-15);
    /// ```
    #[inline]
    pub fn renormalize(self) -> Self {
        self.scale(T::from_f64(1.5) - T::from_f64(0.5) * self.norm_squared())
    }
    /// `if mask { a } else { b }`, per lane.
    #[inline]
    pub fn select(mask: T::Mask, a: Self, b: Self) -> Self {
        Self::new(
            T::select(mask, a.w, b.w),
            T::select(mask, a.x, b.x),
            T::select(mask, a.y, b.y),
            T::select(mask, a.z, b.z),
        )
    }
    /// Per lane: all four components finite.
    #[inline]
    pub fn is_finite(self) -> T::Mask {
        self.w.is_finite() & self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
    /// Lane `i` as a scalar quaternion.
    ///
    /// # Panics
    /// If `i >= T::LANES` (a programming error, like an index out of bounds).
    #[inline]
    pub fn lane(self, i: usize) -> Quat<T::Scalar> {
        assert!(i < T::LANES, "lane {i} of a {}-lane quaternion", T::LANES);
        Quat::new(
            self.w.extract(i),
            self.x.extract(i),
            self.y.extract(i),
            self.z.extract(i),
        )
    }
    /// Builds a lane quaternion from one scalar quaternion per lane.
    #[inline]
    pub fn from_lanes(mut f: impl FnMut(usize) -> Quat<T::Scalar>) -> Self {
        // 16 is at least the widest lane type (f32x8 has 8).
        let mut q = [Quat::<T::Scalar>::identity(); 16];
        for (i, slot) in q.iter_mut().enumerate().take(T::LANES) {
            *slot = f(i);
        }
        Self::new(
            T::from_fn(|i| q[i].w),
            T::from_fn(|i| q[i].x),
            T::from_fn(|i| q[i].y),
            T::from_fn(|i| q[i].z),
        )
    }

    /// Rotates a sensor-frame vector into the earth frame: `q ⊗ [0, v] ⊗ q*`.
    ///
    /// Uses `t = 2·(q_v × v)`, `v' = v + w·t + q_v × t` (15 multiplications instead of 32);
    /// exact for unit `q`.
    #[inline]
    pub fn rotate(self, v: Vec3<T>) -> Vec3<T> {
        let qv = self.vector();
        let t = qv.cross(v) * T::from_f64(2.0);
        v + t * self.w + qv.cross(t)
    }
    /// Rotates an earth-frame vector into the sensor frame: `q* ⊗ [0, v] ⊗ q`.
    #[inline]
    pub fn rotate_inverse(self, v: Vec3<T>) -> Vec3<T> {
        self.conj().rotate(v)
    }

    /// Earth-up `[0, 0, 1]` (ENU) in the sensor frame, `q* ⊗ [0, e_z] ⊗ q`: the third row of
    /// the rotation matrix, `[2(xz − wy), 2(yz + wx), 1 − 2(x² + y²)]` for a unit `q`. Equals
    /// [`rotate_inverse`](Self::rotate_inverse) of `e_z` up to rounding, in a third of the
    /// operations (a product with a zero component cannot be folded away in IEEE arithmetic).
    #[inline]
    pub fn up_in_sensor(self) -> Vec3<T> {
        self.half_up_in_sensor() * T::from_f64(2.0)
    }
    /// Half of [`up_in_sensor`](Self::up_in_sensor), `[xz − wy, yz + wx, ½ − (x² + y²)]`:
    /// the same bits halved (scaling by two commutes with rounding), one multiply fewer for a
    /// caller that folds the factor two into its gains.
    #[inline]
    pub fn half_up_in_sensor(self) -> Vec3<T> {
        let (w, x, y, z) = (self.w, self.x, self.y, self.z);
        Vec3::new(
            x * z - w * y,
            y * z + w * x,
            T::from_f64(0.5) - (x * x + y * y),
        )
    }

    /// The quaternion exponential of a pure quaternion `[0, v]`:
    /// `[cos|v|, sin|v|·v/|v|]`.
    ///
    /// Below `|v| = 1/4` (every gyro step and filter correction at IMU rates) it is the
    /// Taylor series of `cos a` and `sin(a)/a` in `a² = |v|²` through `a¹⁰`: the first omitted
    /// terms (`a¹²/12!`, `a¹²/13!`) are below `1.3·10⁻¹⁶`, half an f64 ulp of 1, so the series
    /// is as accurate as the trigonometric functions and needs no square root, trigonometry
    /// or division — the exponential sits on the dependency chain of every filter update.
    /// Larger angles take `sin_cos` (computed only when some lane needs it; each lane's result
    /// depends on its own input only).
    #[inline]
    pub fn exp(v: Vec3<T>) -> Self {
        let (cos, sinc) = Self::exp_cos_sinc(v.norm_squared());
        Self::from_parts(cos, v * sinc)
    }
    /// `cos a` and `sin(a)/a` of `a = √a2`: the coefficients of [`exp`](Self::exp), which is
    /// `[cos a, v·sin(a)/a]` for `a2 = |v|²`; the same rule (series below `|v| = 1/4`).
    #[inline]
    pub(crate) fn exp_cos_sinc(a2: T) -> (T, T) {
        let f = |x: f64| T::from_f64(x);
        let cos = T::one()
            - a2 * (f(1.0 / 2.0)
                - a2 * (f(1.0 / 24.0)
                    - a2 * (f(1.0 / 720.0)
                        - a2 * (f(1.0 / 40_320.0) - a2 * f(1.0 / 3_628_800.0)))));
        let sinc = T::one()
            - a2 * (f(1.0 / 6.0)
                - a2 * (f(1.0 / 120.0)
                    - a2 * (f(1.0 / 5_040.0)
                        - a2 * (f(1.0 / 362_880.0) - a2 * f(1.0 / 39_916_800.0)))));
        let small = a2.simd_lt(f(EXP_SERIES_LIMIT * EXP_SERIES_LIMIT));
        if small.all() {
            return (cos, sinc);
        }
        let a = a2.sqrt();
        let (s, c) = a.sin_cos();
        let large_sinc = s / T::select(small, T::one(), a);
        (T::select(small, cos, c), T::select(small, sinc, large_sinc))
    }
    /// `self ⊗ [0, v]`, without the products by the pure quaternion's zero (which IEEE
    /// arithmetic cannot fold away): `[−q_v·v, q_w·v + q_v × v]`.
    #[inline]
    pub(crate) fn times_pure(self, v: Vec3<T>) -> Self {
        let (w, x, y, z) = (self.w, self.x, self.y, self.z);
        Self::new(
            -(x.mul_add(v.x, y.mul_add(v.y, z * v.z))),
            w.mul_add(v.x, y.mul_add(v.z, -(z * v.y))),
            w.mul_add(v.y, z.mul_add(v.x, -(x * v.z))),
            w.mul_add(v.z, x.mul_add(v.y, -(y * v.x))),
        )
    }
    /// `[0, v] ⊗ self`, without the products by the pure quaternion's zero:
    /// `[−v·q_v, q_w·v + v × q_v]`.
    #[inline]
    pub(crate) fn pure_times(self, v: Vec3<T>) -> Self {
        let (w, x, y, z) = (self.w, self.x, self.y, self.z);
        Self::new(
            -(x.mul_add(v.x, y.mul_add(v.y, z * v.z))),
            w.mul_add(v.x, v.y.mul_add(z, -(v.z * y))),
            w.mul_add(v.y, v.z.mul_add(x, -(v.x * z))),
            w.mul_add(v.z, v.x.mul_add(y, -(v.y * x))),
        )
    }
    /// The rotation by the rotation vector `phi` (axis·angle, rad): `exp(phi/2)`.
    ///
    /// This is the exact gyro-integration step: `q_{k+1} = q_k ⊗ from_rotation_vector(ω·dt)`.
    #[inline]
    pub fn from_rotation_vector(phi: Vec3<T>) -> Self {
        Self::exp(phi * T::from_f64(0.5))
    }
    /// The rotation by `angle` (rad) about a unit `axis`.
    #[inline]
    pub fn from_axis_angle(axis: Vec3<T>, angle: T) -> Self {
        let (s, c) = (angle * T::from_f64(0.5)).sin_cos();
        Self::from_parts(c, axis * s)
    }
    /// The quaternion logarithm of a unit quaternion, `[0, θ·u]` returned as the vector
    /// `θ·u` where `q = [cos θ, sin θ·u]`, `θ = atan2(|q_v|, w) ∈ [0, π]`; series near zero.
    #[inline]
    pub fn log(self) -> Vec3<T> {
        let s = self.vector().norm();
        let theta = s.atan2(self.w);
        // θ/s with s = sin θ·|q|, near 0: (1/w)·(1 - s²/(3w²)) for w > 0.
        let r2 = s.sq() / self.w.sq();
        let series = (T::one() - r2 * T::from_f64(1.0 / 3.0)) / self.w;
        let small = s.simd_lt(T::from_f64(SERIES_LIMIT) * self.w.abs()) & self.w.simd_gt(T::zero());
        self.vector() * T::select(small, series, theta / s)
    }
    /// The rotation vector (axis·angle, rad, angle in `[0, π]`) of a unit quaternion,
    /// taking the shorter way (`q` and `-q` give the same result).
    #[inline]
    pub fn to_rotation_vector(self) -> Vec3<T> {
        let q = Self::select(self.w.simd_lt(T::zero()), -self, self);
        q.log() * T::from_f64(2.0)
    }
    /// Rotation angle between two orientations, rad in `[0, π]`, robust near zero
    /// (`2·atan2(|v|, |w|)` of `a* ⊗ b` rather than `2·acos(|a·b|)`).
    #[inline]
    pub fn angle_to(self, other: Self) -> T {
        let d = self.conj() * other;
        d.vector().norm().atan2(d.w.abs()) * T::from_f64(2.0)
    }

    /// `q` or `-q`, whichever is in the hemisphere of `reference` (non-negative dot product).
    ///
    /// Averaging or blending antipodal quaternions without this is a real bug.
    #[inline]
    pub fn align_to(self, reference: Self) -> Self {
        Self::select(self.dot(reference).simd_lt(T::zero()), -self, self)
    }
    /// Normalised linear interpolation from `self` (t = 0) to `other` (t = 1), hemisphere-aligned.
    #[inline]
    pub fn nlerp(self, other: Self, t: T) -> Self {
        let b = other.align_to(self);
        (self.scale(T::one() - t) + b.scale(t)).normalize()
    }
    /// Spherical linear interpolation from `self` (t = 0) to `other` (t = 1) along the
    /// shorter arc; falls back to [`nlerp`](Self::nlerp) when the two are nearly parallel.
    #[inline]
    pub fn slerp(self, other: Self, t: T) -> Self {
        let b = other.align_to(self);
        let d = self.dot(b).min(T::one());
        let theta = d.acos();
        let s = theta.sin();
        let wa = ((T::one() - t) * theta).sin() / s;
        let wb = (t * theta).sin() / s;
        let spherical = (self.scale(wa) + b.scale(wb)).normalize();
        let near = d.simd_gt(T::from_f64(0.9995));
        Self::select(near, self.nlerp(b, t), spherical)
    }

    /// The rotation matrix `R` with `R·v = q ⊗ v ⊗ q*` (sensor to earth), for unit `q`.
    #[inline]
    pub fn to_rotation_matrix(self) -> Mat<T, 3, 3> {
        let two = T::from_f64(2.0);
        let (w, x, y, z) = (self.w, self.x, self.y, self.z);
        let (xx, yy, zz) = (x * x, y * y, z * z);
        let (xy, xz, yz) = (x * y, x * z, y * z);
        let (wx, wy, wz) = (w * x, w * y, w * z);
        let one = T::one();
        Mat::from_rows([
            [one - two * (yy + zz), two * (xy - wz), two * (xz + wy)],
            [two * (xy + wz), one - two * (xx + zz), two * (yz - wx)],
            [two * (xz - wy), two * (yz + wx), one - two * (xx + yy)],
        ])
    }
    /// The unit quaternion of a rotation matrix, by the largest-pivot (Shepperd 1978) form:
    /// of `w, x, y, z` the largest in magnitude is taken from the diagonal and the others
    /// from off-diagonal sums, so no square root of a near-zero number decides the result.
    /// The result has `w ≥ 0`.
    pub fn from_rotation_matrix(m: &Mat<T, 3, 3>) -> Self {
        let r = &m.m;
        let one = T::one();
        let quarter = T::from_f64(0.25);
        let trace = r[0][0] + r[1][1] + r[2][2];
        let (d0, d1, d2) = (r[0][0], r[1][1], r[2][2]);
        // Candidates with w, x, y or z as the pivot p: 4·p² = 1 ± d0 ± d1 ± d2, and the other
        // components are off-diagonal sums divided by 4·p.
        let half = T::from_f64(0.5);
        let pivot = |p2: T| p2.max(T::zero()).sqrt() * half;
        let (pw, px) = (pivot(one + trace), pivot(one + d0 - d1 - d2));
        let (py, pz) = (pivot(one - d0 + d1 - d2), pivot(one - d0 - d1 + d2));
        let (kw, kx, ky, kz) = (quarter / pw, quarter / px, quarter / py, quarter / pz);
        let (s21, s02, s10) = (r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]);
        let (a01, a02, a12) = (r[0][1] + r[1][0], r[0][2] + r[2][0], r[1][2] + r[2][1]);
        let qw = Self::new(pw, s21 * kw, s02 * kw, s10 * kw);
        let qx = Self::new(s21 * kx, px, a01 * kx, a02 * kx);
        let qy = Self::new(s02 * ky, a01 * ky, py, a12 * ky);
        let qz = Self::new(s10 * kz, a02 * kz, a12 * kz, pz);
        let use_w = trace.simd_ge(d0) & trace.simd_ge(d1) & trace.simd_ge(d2);
        let use_x = !use_w & d0.simd_ge(d1) & d0.simd_ge(d2);
        let use_y = !use_w & !use_x & d1.simd_ge(d2);
        let q = Self::select(
            use_w,
            qw,
            Self::select(use_x, qx, Self::select(use_y, qy, qz)),
        );
        let q = q.normalize();
        Self::select(q.w.simd_lt(T::zero()), -q, q)
    }

    /// The orientation `qz(yaw) ⊗ qy(pitch) ⊗ qx(roll)` from ZYX Euler angles (rad).
    #[inline]
    pub fn from_euler_zyx(yaw: T, pitch: T, roll: T) -> Self {
        let half = T::from_f64(0.5);
        let (sy, cy) = (yaw * half).sin_cos();
        let (sp, cp) = (pitch * half).sin_cos();
        let (sr, cr) = (roll * half).sin_cos();
        Self::new(
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        )
    }
    /// ZYX Euler angles `(yaw, pitch, roll)` in rad: yaw and roll in `[-π, π]`, pitch in
    /// `[-π/2, π/2]`.
    ///
    /// Pitch is `atan2(-R20, hypot(R21, R22))`, well conditioned up to ±90° (unlike `asin`).
    /// Near gimbal lock (`cos(pitch) < sqrt(eps)`) yaw and roll are not separable; there roll
    /// is set to 0 and yaw = `atan2(-R01, R11)` carries the whole heading, which reproduces the
    /// rotation to within about `2·sqrt(eps)` rad (7e-4 in f32, 3e-8 in f64).
    pub fn to_euler_zyx(self) -> (T, T, T) {
        let two = T::from_f64(2.0);
        let one = T::one();
        let (w, x, y, z) = (self.w, self.x, self.y, self.z);
        let r20 = two * (x * z - w * y);
        let r21 = two * (y * z + w * x);
        let r22 = one - two * (x * x + y * y);
        let r10 = two * (x * y + w * z);
        let r00 = one - two * (y * y + z * z);
        let r01 = two * (x * y - w * z);
        let r11 = one - two * (x * x + z * z);
        let cos_pitch = (r21 * r21 + r22 * r22).sqrt();
        let pitch = (-r20).atan2(cos_pitch);
        // Outside the lock the angles carry eps/cos(pitch) of rounding; inside, dropping roll costs
        // up to 2·cos(pitch): the two balance at cos(pitch) = sqrt(eps).
        let lock = cos_pitch.simd_lt(T::from_f64(T::EPSILON.sqrt()));
        let yaw = T::select(lock, (-r01).atan2(r11), r10.atan2(r00));
        let roll = T::select(lock, T::zero(), r21.atan2(r22));
        (yaw, pitch, roll)
    }

    /// Splits `q = q_heading ⊗ q_inclination` into a rotation about earth-z (heading) and one
    /// about a horizontal axis (inclination, zero z-component).
    ///
    /// Returns `(heading, q_inclination)` with heading in rad, `[-π, π]`. When the
    /// inclination is 180° the heading is undefined; it is returned as 0.
    pub fn heading_inclination(self) -> (T, Self) {
        let hn2 = self.w.sq() + self.z.sq();
        let defined = hn2.simd_gt(T::from_f64(1e-24));
        let heading = T::select(
            defined,
            (T::from_f64(2.0) * self.z.atan2(self.w)).wrap_pi(),
            T::zero(),
        );
        let (hs, hc) = (heading * T::from_f64(0.5)).sin_cos();
        let q_heading = Self::new(hc, T::zero(), T::zero(), hs);
        let mut incl = q_heading.conj() * self;
        incl.z = T::zero();
        (heading, incl)
    }
    /// The heading rotation `qz(psi) = [cos(psi/2), 0, 0, sin(psi/2)]` (rad, about earth-z).
    #[inline]
    pub fn from_heading(psi: T) -> Self {
        let (s, c) = (psi * T::from_f64(0.5)).sin_cos();
        Self::new(c, T::zero(), T::zero(), s)
    }
}

impl<T: Lane> From<[T; 4]> for Quat<T> {
    /// `[w, x, y, z]`, not normalised.
    fn from(q: [T; 4]) -> Self {
        Self::from_array(q)
    }
}

impl<T: Lane> From<Quat<T>> for [T; 4] {
    /// `[w, x, y, z]`.
    fn from(q: Quat<T>) -> Self {
        q.to_array()
    }
}

impl<T: Lane> Mul for Quat<T> {
    type Output = Self;
    /// Hamilton product `self ⊗ rhs`: apply `rhs` first, then `self`.
    #[inline]
    fn mul(self, r: Self) -> Self {
        let (a, b) = (self, r);
        Self::new(
            a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
            a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
            a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
            a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        )
    }
}
impl<T: Lane> Neg for Quat<T> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::new(-self.w, -self.x, -self.y, -self.z)
    }
}
impl<T: Lane> Add for Quat<T> {
    type Output = Self;
    /// Component-wise sum (a blend, not a composition of rotations).
    #[inline]
    fn add(self, o: Self) -> Self {
        Self::new(self.w + o.w, self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<T: Lane> Sub for Quat<T> {
    type Output = Self;
    /// Component-wise difference.
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self::new(self.w - o.w, self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<T: Lane> rootfuse_lane::Select<T::Mask> for Quat<T> {
    #[inline]
    fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
        Self::select(mask, *a, *b)
    }
}
