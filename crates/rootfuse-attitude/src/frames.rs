//! Earth-frame conventions as types: [`Enu`] (the library's), [`Ned`] and [`Nwu`].
//!
//! Every filter estimates `q` rotating sensor to **ENU** (x east, y north, z up). Users of
//! other conventions convert the result by type, never by a runtime flag: an
//! [`Attitude<T, F>`] carries its earth frame `F` in its type, and [`Attitude::to`] is the only
//! way to change it. The sensor frame is untouched by the conversion (it is whatever the IMU's
//! axes are; mount the sensor FRD, x forward, y right, z down, to read aerospace yaw, pitch
//! and roll from an [`Attitude<T, Ned>`]).
//!
//! ```
//! use rootfuse_attitude::frames::{Attitude, Enu, Ned};
//! use rootfuse_attitude::{Quat, Vec3};
//!
//! // A level FRD sensor pointing east, as a filter reports it (sensor to ENU).
//! let x_fwd = Vec3::new(1.0, 0.0, 0.0); // east
//! let y_right = Vec3::new(0.0, -1.0, 0.0); // south
//! let z_down = Vec3::new(0.0, 0.0, -1.0);
//! let m = rootfuse_attitude::Mat::from_fn(|i, j| [x_fwd, y_right, z_down][j].to_array()[i]);
//! let enu = Attitude::<f64, Enu>::new(Quat::from_rotation_matrix(&m));
//! let (yaw, pitch, roll) = enu.to::<Ned>().euler_zyx();
//! assert!((yaw - core::f64::consts::FRAC_PI_2).abs() < 1e-12); // heading 90°: east
//! assert!(pitch.abs() < 1e-12 && roll.abs() < 1e-12);
//! ```

use crate::{Quat, Vec3};
use core::marker::PhantomData;
use rootfuse_lane::Lane;

/// An earth-frame convention: how its coordinates relate to ENU.
pub trait EarthFrame: Copy + core::fmt::Debug + Default {
    /// Short name (`"ENU"`, `"NED"`, `"NWU"`).
    const NAME: &'static str;
    /// The rotation `C` taking ENU coordinates to this frame's, `v_F = C·v_ENU`, as a unit
    /// quaternion (`v_F = c ⊗ v_ENU ⊗ c*`).
    fn from_enu<T: Lane>() -> Quat<T>;
    /// Earth-up in this frame's coordinates.
    fn up<T: Lane>() -> Vec3<T> {
        Self::from_enu::<T>().rotate(Vec3::new(T::zero(), T::zero(), T::one()))
    }
    /// North in this frame's coordinates.
    fn north<T: Lane>() -> Vec3<T> {
        Self::from_enu::<T>().rotate(Vec3::new(T::zero(), T::one(), T::zero()))
    }
}

/// East, north, up: the library's frame (`C = I`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Enu;

/// North, east, down: `v_NED = (v_n, v_e, −v_u)`; `C` is the half turn about `(1, 1, 0)/√2`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ned;

/// North, west, up: `v_NWU = (v_n, −v_e, v_u)`; `C` is −90° about up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Nwu;

impl EarthFrame for Enu {
    const NAME: &'static str = "ENU";
    fn from_enu<T: Lane>() -> Quat<T> {
        Quat::identity()
    }
}

impl EarthFrame for Ned {
    const NAME: &'static str = "NED";
    fn from_enu<T: Lane>() -> Quat<T> {
        let h = T::from_f64(core::f64::consts::FRAC_1_SQRT_2);
        Quat::new(T::zero(), h, h, T::zero())
    }
}

impl EarthFrame for Nwu {
    const NAME: &'static str = "NWU";
    fn from_enu<T: Lane>() -> Quat<T> {
        let h = T::from_f64(core::f64::consts::FRAC_1_SQRT_2);
        Quat::new(h, T::zero(), T::zero(), -h)
    }
}

/// An orientation, sensor to the earth frame `F`: `v_F = q ⊗ v_sensor ⊗ q*`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attitude<T: Lane, F: EarthFrame> {
    q: Quat<T>,
    frame: PhantomData<F>,
}

impl<T: Lane, F: EarthFrame> Attitude<T, F> {
    /// Wraps a quaternion that rotates sensor to `F`.
    pub fn new(q: Quat<T>) -> Self {
        Self {
            q,
            frame: PhantomData,
        }
    }

    /// The quaternion, sensor to `F`.
    pub fn quat(&self) -> Quat<T> {
        self.q
    }

    /// The same orientation expressed in frame `G`: `q_G = c_G ⊗ c_F* ⊗ q_F`.
    pub fn to<G: EarthFrame>(self) -> Attitude<T, G> {
        let c = G::from_enu::<T>() * F::from_enu::<T>().conj();
        Attitude::new(c * self.q)
    }

    /// ZYX Euler angles `(yaw, pitch, roll)` (rad) of the rotation sensor → `F` (see
    /// [`Quat::to_euler_zyx`]). In [`Ned`] with an FRD sensor these are the aerospace
    /// heading (clockwise from north), pitch (nose up) and roll (right wing down).
    pub fn euler_zyx(&self) -> (T, T, T) {
        self.q.to_euler_zyx()
    }

    /// A sensor-frame vector in `F` coordinates.
    pub fn rotate(&self, v: Vec3<T>) -> Vec3<T> {
        self.q.rotate(v)
    }
}
