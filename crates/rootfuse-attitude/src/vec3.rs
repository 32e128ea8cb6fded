//! Three-vectors of lanes.

use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};
use rootfuse_lane::{Lane, Vector};

/// A 3-vector (`[x, y, z]`); the frame is given by context (sensor or earth).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3<T> {
    /// First component.
    pub x: T,
    /// Second component.
    pub y: T,
    /// Third component.
    pub z: T,
}

impl<T: Lane> Vec3<T> {
    /// From components.
    #[inline]
    pub const fn new(x: T, y: T, z: T) -> Self {
        Self { x, y, z }
    }
    /// The zero vector.
    #[inline]
    pub fn zero() -> Self {
        Self::new(T::zero(), T::zero(), T::zero())
    }
    /// From an `f64` array (constants, test values).
    #[inline]
    pub fn from_f64(v: [f64; 3]) -> Self {
        Self::new(T::from_f64(v[0]), T::from_f64(v[1]), T::from_f64(v[2]))
    }
    /// As an array `[x, y, z]`.
    #[inline]
    pub fn to_array(self) -> [T; 3] {
        [self.x, self.y, self.z]
    }
    /// From an array `[x, y, z]`; also `Vec3::from([x, y, z])`.
    ///
    /// ```
    /// use rootfuse_attitude::Vec3;
    /// let v = Vec3::from([0.0_f32, 0.0, 9.81]);
    /// assert_eq!(v.z, 9.81);
    /// assert_eq!(<[f32; 3]>::from(v), [0.0, 0.0, 9.81]);
    /// ```
    #[inline]
    pub fn from_array(v: [T; 3]) -> Self {
        Self::new(v[0], v[1], v[2])
    }
    /// As a column vector for the matrix kernels.
    #[inline]
    pub fn to_vector(self) -> Vector<T, 3> {
        Vector::from_column(self.to_array())
    }
    /// Dot product.
    #[inline]
    pub fn dot(self, o: Self) -> T {
        self.x.mul_add(o.x, self.y.mul_add(o.y, self.z * o.z))
    }
    /// Cross product `self × o` (right-handed).
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    /// Squared Euclidean norm.
    #[inline]
    pub fn norm_squared(self) -> T {
        self.dot(self)
    }
    /// Euclidean norm.
    #[inline]
    pub fn norm(self) -> T {
        self.norm_squared().sqrt()
    }
    /// Unit vector and a per-lane mask of where that was possible.
    ///
    /// Lanes whose squared norm is zero, subnormal-small, NaN or infinite (for example
    /// `1e20` in every axis in f32) are not normalisable: they get the zero vector and a
    /// false mask bit, so callers can reject that sample for that lane.
    #[inline]
    pub fn try_normalize(self) -> (Self, T::Mask) {
        let n2 = self.norm_squared();
        let ok = n2.simd_gt(T::from_f64(1e-30)) & n2.is_finite();
        let inv = T::one() / n2.sqrt();
        (Self::select(ok, self * inv, Self::zero()), ok)
    }
    /// `if mask { a } else { b }`, per lane.
    #[inline]
    pub fn select(mask: T::Mask, a: Self, b: Self) -> Self {
        Self::new(
            T::select(mask, a.x, b.x),
            T::select(mask, a.y, b.y),
            T::select(mask, a.z, b.z),
        )
    }
    /// Per lane: all three components finite.
    #[inline]
    pub fn is_finite(self) -> T::Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
    /// Lane `i` as a scalar vector.
    ///
    /// # Panics
    /// If `i >= T::LANES` (a programming error, like an index out of bounds).
    #[inline]
    pub fn lane(self, i: usize) -> Vec3<T::Scalar> {
        assert!(i < T::LANES, "lane {i} of a {}-lane vector", T::LANES);
        Vec3::new(self.x.extract(i), self.y.extract(i), self.z.extract(i))
    }
    /// Builds a lane vector from one scalar vector per lane.
    #[inline]
    pub fn from_lanes(mut f: impl FnMut(usize) -> Vec3<T::Scalar>) -> Self {
        // 16 is at least the widest lane type (f32x8 has 8).
        let mut v = [Vec3::<T::Scalar>::zero(); 16];
        for (i, slot) in v.iter_mut().enumerate().take(T::LANES) {
            *slot = f(i);
        }
        Self::new(
            T::from_fn(|i| v[i].x),
            T::from_fn(|i| v[i].y),
            T::from_fn(|i| v[i].z),
        )
    }
    /// Largest absolute component over all lanes (diagnostics, tests).
    pub fn max_abs(self) -> f64 {
        self.to_vector().max_abs()
    }
}

impl<T: Lane> From<[T; 3]> for Vec3<T> {
    /// `[x, y, z]`.
    fn from(v: [T; 3]) -> Self {
        Self::from_array(v)
    }
}

impl<T: Lane> From<Vec3<T>> for [T; 3] {
    /// `[x, y, z]`.
    fn from(v: Vec3<T>) -> Self {
        v.to_array()
    }
}

impl<T: Lane> Add for Vec3<T> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<T: Lane> Sub for Vec3<T> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<T: Lane> AddAssign for Vec3<T> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<T: Lane> SubAssign for Vec3<T> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl<T: Lane> Neg for Vec3<T> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<T: Lane> Mul<T> for Vec3<T> {
    type Output = Self;
    #[inline]
    fn mul(self, s: T) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}

impl<T: Lane> rootfuse_lane::Select<T::Mask> for Vec3<T> {
    #[inline]
    fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
        Self::select(mask, *a, *b)
    }
}
