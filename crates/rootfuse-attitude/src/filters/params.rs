//! Named, validated filter parameters (`key=value` overrides), shared by the CLI, the batch
//! engine and the tests.

#[cfg(feature = "std")]
use core::fmt;
use rootfuse_lane::Lane;

/// 6D (gyroscope and accelerometer: heading unobservable, free) or 9D (with the
/// magnetometer: heading toward magnetic north) operation of a filter.
///
/// As a `key=value` parameter it is written `dof=6` or `dof=9`; any other number is refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Dof {
    /// Gyroscope and accelerometer only; the magnetometer is ignored (not even screened).
    Six,
    /// Gyroscope, accelerometer and magnetometer.
    #[default]
    Nine,
}

impl Dof {
    /// True for 9D: the filter reads the magnetometer.
    pub const fn uses_magnetometer(self) -> bool {
        matches!(self, Self::Nine)
    }
    /// The number of degrees of freedom: 6 or 9.
    pub const fn count(self) -> u8 {
        match self {
            Self::Six => 6,
            Self::Nine => 9,
        }
    }
    /// `Some` for 6 and 9, `None` for any other number.
    pub const fn from_count(n: u8) -> Option<Self> {
        match n {
            6 => Some(Self::Six),
            9 => Some(Self::Nine),
            _ => None,
        }
    }
}

impl core::fmt::Display for Dof {
    /// `6D` or `9D`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}D", self.count())
    }
}

/// What values a parameter takes; its `f64` form in `key=value` is checked against this.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    /// Any number in the range.
    Real,
    /// A whole number in the range (a fraction is refused, never rounded).
    Integer,
    /// `0` (off) or `1` (on).
    Switch,
    /// `6` or `9` ([`Dof`]).
    Dof,
}

impl ParamKind {
    /// A short description for listings: `"number"`, `"whole number"`, `"0 or 1"`, `"6 or 9"`.
    pub const fn describe(self) -> &'static str {
        match self {
            Self::Real => "number",
            Self::Integer => "whole number",
            Self::Switch => "0 or 1",
            Self::Dof => "6 or 9",
        }
    }
}

/// A parameter's Rust type: its `f64` form for `key=value`, listings and bindings.
pub trait ParamValue: Copy + Default {
    /// What values it takes.
    const KIND: ParamKind;
    /// The value as a number.
    fn to_f64(self) -> f64;
    /// The value of a number, `None` when the number is not one of this type (a fraction
    /// for an integer, anything but 0/1 for a switch, anything but 6/9 for [`Dof`]).
    fn from_f64(v: f64) -> Option<Self>;
}

impl ParamValue for f64 {
    const KIND: ParamKind = ParamKind::Real;
    fn to_f64(self) -> f64 {
        self
    }
    fn from_f64(v: f64) -> Option<Self> {
        Some(v)
    }
}

impl ParamValue for u32 {
    const KIND: ParamKind = ParamKind::Integer;
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn from_f64(v: f64) -> Option<Self> {
        let whole = v >= 0.0 && v <= f64::from(u32::MAX) && v == libm::trunc(v);
        whole.then_some(v as u32)
    }
}

impl ParamValue for bool {
    const KIND: ParamKind = ParamKind::Switch;
    fn to_f64(self) -> f64 {
        if self { 1.0 } else { 0.0 }
    }
    fn from_f64(v: f64) -> Option<Self> {
        match v {
            0.0 => Some(false),
            1.0 => Some(true),
            _ => None,
        }
    }
}

impl ParamValue for Dof {
    const KIND: ParamKind = ParamKind::Dof;
    fn to_f64(self) -> f64 {
        f64::from(self.count())
    }
    fn from_f64(v: f64) -> Option<Self> {
        match v {
            6.0 => Some(Self::Six),
            9.0 => Some(Self::Nine),
            _ => None,
        }
    }
}

/// The parameter sets of a filter's lanes `T`: one set shared by every lane, or one set per
/// lane, so that channels with different parameters can share one SIMD chunk.
///
/// Real-valued parameters become per-lane coefficients ([`coef`](Self::coef)); the ones that
/// shape the computation itself — `dof`, switches, whole numbers (window lengths) and the
/// screening limits — are one value for the whole chunk, so [`per_lane`](Self::per_lane)
/// refuses sets that differ in one of them (the registry's `FilterSpec::same_structure` says
/// whether two specs can share a chunk).
///
/// ```
/// use rootfuse_attitude::filters::{LaneParams, LaneParamsError, Mahony, MahonyParams};
/// use rootfuse_attitude::{Dof, ImuSample, OrientationFilter, Vec3};
/// use rootfuse_lane::wide::f32x8;
///
/// let mut sets: Vec<MahonyParams> = (0..8)
///     .map(|i| MahonyParams { kp: 0.1 * (i + 1) as f64, ..Default::default() })
///     .collect();
/// let mut lanes = Mahony::<f32x8>::with_lane_params(&LaneParams::per_lane(&sets).unwrap());
/// let mut one = Mahony::<f32>::new(&sets[3]);
/// let v = |x: f32, y: f32, z: f32| Vec3::new(f32x8::splat(x), f32x8::splat(y), f32x8::splat(z));
/// lanes.update(&ImuSample::six_d(v(0.1, 0.0, 0.0), v(0.0, 1.0, 9.8)), f32x8::splat(0.01));
/// one.update(&ImuSample::six_d(Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 1.0, 9.8)), 0.01);
/// assert_eq!(lanes.quat().lane(3), one.quat());
///
/// // A chunk has one `dof`: a set that differs is refused, naming its lane and the key.
/// sets[5].dof = Dof::Six;
/// let refused = LaneParams::<_, f32x8>::per_lane(&sets).unwrap_err();
/// assert_eq!(refused, LaneParamsError::Structural { lane: 5, name: "dof" });
/// ```
#[derive(Debug)]
pub struct LaneParams<'a, P, T> {
    sets: &'a [P],
    lanes: core::marker::PhantomData<fn() -> T>,
}

// Not derived: a derive would ask `T: Clone`, which the lane types are but a generic caller
// would have to state.
impl<P, T> Clone for LaneParams<'_, P, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<P, T> Copy for LaneParams<'_, P, T> {}

impl<'a, P: ParamSet, T: Lane> LaneParams<'a, P, T> {
    /// One set for every lane (not validated here: `try_new` on the filter does that).
    pub fn uniform(p: &'a P) -> Self {
        Self {
            sets: core::slice::from_ref(p),
            lanes: core::marker::PhantomData,
        }
    }
    /// One set per lane (`sets[i]` for lane `i`), or one set for all (`sets.len() == 1`).
    ///
    /// Refused: a count other than 1 or `T::LANES`, a set out of range
    /// ([`validate`](crate::filters::MahonyParams::validate)), and a set that differs from
    /// set 0 in a parameter the lanes of one chunk share ([`ParamInfo::per_lane`] false); the
    /// error names the lane and the parameter.
    pub fn per_lane(sets: &'a [P]) -> Result<Self, LaneParamsError> {
        if sets.len() != 1 && sets.len() != T::LANES {
            return Err(LaneParamsError::Count {
                sets: sets.len(),
                lanes: T::LANES,
            });
        }
        for (lane, set) in sets.iter().enumerate() {
            set.validate_set()
                .map_err(|error| LaneParamsError::Invalid { lane, error })?;
            if let Some(name) = sets[0].structural_difference(set) {
                return Err(LaneParamsError::Structural { lane, name });
            }
        }
        Ok(Self {
            sets,
            lanes: core::marker::PhantomData,
        })
    }
    /// The first set: where the structural parameters come from.
    pub fn first(&self) -> &'a P {
        &self.sets[0]
    }
    /// Every set: one, or one per lane.
    pub fn sets(&self) -> &'a [P] {
        self.sets
    }
    /// A per-lane coefficient `f(set)`, computed in `f64` and rounded to the lane type once:
    /// lane `i` holds exactly what a scalar filter built from its set holds.
    pub fn coef(&self, f: impl Fn(&P) -> f64) -> T {
        match self.sets {
            [one] => T::from_f64(f(one)),
            // `per_lane` made `sets.len() == T::LANES`.
            sets => T::from_fn(|i| T::from_f64(f(&sets[i])).extract(0)),
        }
    }
}

/// Why [`LaneParams::per_lane`] refused a list of parameter sets. Available without `std`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LaneParamsError {
    /// The number of sets is neither 1 nor the lane count.
    Count {
        /// Sets given.
        sets: usize,
        /// Lanes of the filter's lane type.
        lanes: usize,
    },
    /// The set of `lane` differs from set 0 in a parameter every lane of a chunk shares.
    Structural {
        /// The lane (index into the sets).
        lane: usize,
        /// The parameter.
        name: &'static str,
    },
    /// The set of `lane` has a parameter outside its range.
    Invalid {
        /// The lane (index into the sets).
        lane: usize,
        /// The parameter and its range.
        error: InvalidParam,
    },
}

impl core::fmt::Display for LaneParamsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Count { sets, lanes } => write!(
                f,
                "{sets} parameter sets for {lanes} lanes: give one set, or one per lane"
            ),
            Self::Structural { lane, name } => write!(
                f,
                "lane {lane}: parameter `{name}` differs from lane 0's; lanes of one chunk \
                 share it (run such channels in chunks of their own)"
            ),
            Self::Invalid { lane, error } => write!(f, "lane {lane}: {error}"),
        }
    }
}

impl core::error::Error for LaneParamsError {}

/// A filter's parameter struct, also without `std`: the range check and which parameters
/// the lanes of one chunk must share. Every `*Params` struct implements it.
pub trait ParamSet: Clone {
    /// Checks every parameter against its range (the struct's own `validate`).
    fn validate_set(&self) -> Result<(), InvalidParam>;
    /// The first parameter that the lanes of one chunk share ([`ParamInfo::per_lane`]
    /// false) and that differs between `self` and `other`; `None` when both can run in one
    /// chunk.
    fn structural_difference(&self, other: &Self) -> Option<&'static str>;
}

/// One parameter's description.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamInfo {
    /// Name used in `key=value`.
    pub name: &'static str,
    /// What values it takes (real, whole number, switch, 6/9).
    pub kind: ParamKind,
    /// The value may differ between the lanes of one SIMD chunk ([`LaneParams`]); the others
    /// (structural: `dof`, switches, whole numbers, screening limits, and real parameters that
    /// shape an internal estimator) must be equal for channels to share a chunk.
    pub per_lane: bool,
    /// Default value.
    pub default: f64,
    /// Unit (`"rad/s"`, `"s"`, `"1"` for dimensionless, …).
    pub unit: &'static str,
    /// Smallest accepted value (inclusive).
    pub min: f64,
    /// Largest accepted value (inclusive).
    pub max: f64,
    /// What it does.
    pub doc: &'static str,
}

/// A parameter value outside its accepted range `[min, max]` (NaN is outside every range):
/// what [`validate`](crate::filters::MahonyParams::validate) on a parameter struct reports.
/// Available without `std`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InvalidParam {
    /// Parameter name.
    pub name: &'static str,
    /// The value found.
    pub value: f64,
    /// Smallest accepted value (inclusive).
    pub min: f64,
    /// Largest accepted value (inclusive).
    pub max: f64,
    /// The parameter's unit (`"rad/s"`, …; `"1"` or empty for none).
    pub unit: &'static str,
}

impl core::fmt::Display for InvalidParam {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let Self {
            name,
            value,
            min,
            max,
            unit,
        } = self;
        write!(f, "parameter `{name}` = {value} is outside [{min}, {max}]")?;
        match *unit {
            "" | "1" => Ok(()),
            unit => write!(f, " {unit}"),
        }
    }
}

impl core::error::Error for InvalidParam {}

#[cfg(feature = "std")]
impl From<InvalidParam> for ParamError {
    fn from(e: InvalidParam) -> Self {
        Self::OutOfRange {
            name: e.name,
            value: e.value,
            min: e.min,
            max: e.max,
            unit: e.unit,
        }
    }
}

/// Why a parameter could not be set.
#[cfg(feature = "std")]
#[derive(Clone, Debug, PartialEq)]
pub enum ParamError {
    /// No parameter of that name; the valid names are listed.
    Unknown {
        /// The name given.
        name: std::string::String,
        /// The names this filter accepts.
        valid: std::vec::Vec<&'static str>,
    },
    /// The value is not a number.
    NotANumber {
        /// Parameter name.
        name: &'static str,
        /// The text given.
        value: std::string::String,
    },
    /// The value is outside the accepted range.
    OutOfRange {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// Smallest accepted.
        min: f64,
        /// Largest accepted.
        max: f64,
        /// The parameter's unit (`"1"` or empty for none).
        unit: &'static str,
    },
    /// The value is in range but not one the parameter takes (a fraction for a whole
    /// number, anything but 0/1 for a switch, anything but 6/9 for `dof`).
    WrongKind {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What the parameter takes.
        kind: ParamKind,
    },
    /// Not of the form `key=value`.
    Syntax(std::string::String),
    /// One parameter given twice to [`FilterSpec::set_all`](crate::registry::FilterSpec::set_all)
    /// (even with the same value): refused so that neither value silently wins.
    Repeated {
        /// Parameter name.
        name: std::string::String,
        /// How it was given first (an option, a column, or the `key=value` text).
        first: std::string::String,
        /// How it was given again.
        second: std::string::String,
    },
}

#[cfg(feature = "std")]
impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unknown { name, valid } => write!(
                f,
                "unknown parameter `{name}` (valid: {})",
                valid.join(", ")
            ),
            Self::NotANumber { name, value } => {
                write!(f, "parameter `{name}`: `{value}` is not a number")
            }
            Self::OutOfRange {
                name,
                value,
                min,
                max,
                unit,
            } => InvalidParam {
                name,
                value: *value,
                min: *min,
                max: *max,
                unit,
            }
            .fmt(f),
            Self::WrongKind { name, value, kind } => write!(
                f,
                "parameter `{name}` = {value} is not allowed: it takes a {}",
                kind.describe()
            ),
            Self::Syntax(text) => write!(f, "`{text}` is not of the form key=value"),
            Self::Repeated {
                name,
                first,
                second,
            } => write!(
                f,
                "`{name}` is given twice: by {first} and by {second}; give it once"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ParamError {}

/// A parameter struct with named, documented, range-checked fields.
#[cfg(feature = "std")]
pub trait Params: Clone + Default + fmt::Debug {
    /// Every parameter with its default, unit, range and description.
    fn info() -> &'static [ParamInfo];
    /// The value of a parameter.
    fn get(&self, name: &str) -> Option<f64>;
    /// Sets a parameter by name after checking its range.
    fn set(&mut self, name: &str, value: f64) -> Result<(), ParamError>;
    /// Applies a `key=value` override.
    fn apply(&mut self, assignment: &str) -> Result<(), ParamError> {
        let (key, value) = assignment
            .split_once('=')
            .ok_or_else(|| ParamError::Syntax(assignment.into()))?;
        let (key, value) = (key.trim(), value.trim());
        let info =
            Self::info()
                .iter()
                .find(|p| p.name == key)
                .ok_or_else(|| ParamError::Unknown {
                    name: key.into(),
                    valid: Self::info().iter().map(|p| p.name).collect(),
                })?;
        let v: f64 = value.parse().map_err(|_| ParamError::NotANumber {
            name: info.name,
            value: value.into(),
        })?;
        self.set(key, v)
    }
}

/// Declares a parameter struct: each field has a type ([`ParamValue`]: `f64`, `u32`, `bool`
/// or [`Dof`]), a default written as a number, a unit, a range, a doc, and optionally the
/// marker `shared` for a real parameter that cannot differ between lanes of one chunk. Every struct also
/// gets the four input-screening limits `max_dt`, `max_gyr`, `max_acc` and `max_mag`
/// ([`ScreenLimits`](super::ScreenLimits)).
macro_rules! params {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[doc = $fdoc:literal])* $field:ident: $ty:ty = $default:expr, $unit:literal, [$min:expr, $max:expr] $(, $shared:ident)?; )*
        }
    ) => {
        $crate::filters::params_with_screening! {
            $(#[$meta])*
            pub struct $name {
                $( $(#[doc = $fdoc])* $field: $ty = $default, $unit, [$min, $max] $(, $shared)?; )*
                /// Largest accepted time step; a sample after a longer gap is skipped whole
                /// (counted in `Rejections::dt`): after a gap the orientation would be a guess.
                max_dt: f64 = 1.0, "s", [1e-6, 1e6], shared;
                /// Largest accepted angular-rate magnitude; a faster sample is skipped whole
                /// (counted in `Rejections::gyr`). The default (35 rad/s, about 2000 °/s) is the
                /// usual MEMS full scale; raise it for a 4000 °/s gyroscope.
                max_gyr: f64 = 35.0, "rad/s", [1e-3, 1e5], shared;
                /// Largest accepted specific-force magnitude; a larger accelerometer sample
                /// only skips the accelerometer correction (counted in `Rejections::acc`, flag
                /// 4) and enters no low-pass or detector. The default (1000 m/s², about 102 g)
                /// is beyond the usual MEMS ranges (±16 g ≈ 157 m/s² up to ±100 g); raise it
                /// for a high-g sensor.
                max_acc: f64 = 1000.0, "m/s²", [1.0, 1e12], shared;
                /// Largest accepted magnetic-field magnitude, in the input's field units; a
                /// larger sample only skips the magnetometer correction (9D; counted in
                /// `Rejections::mag`, flag 8). The default 1000 suits µT (1 mT, fifteen times
                /// the strongest geomagnetic field: only a magnet on the sensor exceeds it)
                /// and gauss; raise it for raw counts or nT.
                max_mag: f64 = 1000.0, "field unit", [1e-9, 1e15], shared;
            }
        }
    };
}
pub(crate) use params;

/// The body of [`params!`] once the screening limits are appended.
macro_rules! params_with_screening {
    (@per_lane $ty:ty) => {
        matches!(<$ty as $crate::filters::ParamValue>::KIND, $crate::filters::ParamKind::Real)
    };
    (@per_lane $ty:ty, shared) => {
        false
    };
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[doc = $fdoc:literal])* $field:ident: $ty:ty = $default:expr, $unit:literal, [$min:expr, $max:expr] $(, $shared:ident)?; )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name {
            $( $(#[doc = $fdoc])* #[doc = concat!("\n\nUnit: ", $unit, ". Default: ", stringify!($default), ".")] pub $field: $ty, )*
        }
        impl Default for $name {
            fn default() -> Self {
                // Every default is a value of its type (tested for every filter), so the
                // fallback never applies.
                Self { $( $field: <$ty as $crate::filters::ParamValue>::from_f64($default).unwrap_or_default(), )* }
            }
        }
        impl $name {
            /// Every parameter with its kind, default, unit, range and description.
            pub const INFO: &'static [$crate::filters::ParamInfo] = &[ $( $crate::filters::ParamInfo {
                name: stringify!($field), kind: <$ty as $crate::filters::ParamValue>::KIND,
                per_lane: $crate::filters::params_with_screening!(@per_lane $ty $(, $shared)?),
                default: $default, unit: $unit, min: $min, max: $max,
                doc: concat!($($fdoc),*).trim_ascii(),
            }, )* ];
            /// Checks every parameter against its range, as `Params::set` does for one: a
            /// struct written as a literal (or changed field by field) is checked here, also
            /// without `std`. The first parameter out of range (or NaN) is the error.
            pub fn validate(&self) -> Result<(), $crate::filters::InvalidParam> {
                $( {
                    let value = $crate::filters::ParamValue::to_f64(self.$field);
                    if !($min..=$max).contains(&value) {
                        return Err($crate::filters::InvalidParam {
                            name: stringify!($field), value, min: $min, max: $max, unit: $unit,
                        });
                    }
                } )*
                Ok(())
            }
            /// The input-screening limits of these parameters.
            pub fn screen_limits(&self) -> $crate::filters::ScreenLimits {
                $crate::filters::ScreenLimits {
                    max_dt: self.max_dt,
                    max_gyr: self.max_gyr,
                    max_acc: self.max_acc,
                    max_mag: self.max_mag,
                }
            }
        }
        impl $crate::filters::ParamSet for $name {
            fn validate_set(&self) -> Result<(), $crate::filters::InvalidParam> {
                self.validate()
            }
            fn structural_difference(&self, other: &Self) -> Option<&'static str> {
                $( if !$crate::filters::params_with_screening!(@per_lane $ty $(, $shared)?)
                    && $crate::filters::ParamValue::to_f64(self.$field)
                        != $crate::filters::ParamValue::to_f64(other.$field)
                {
                    return Some(stringify!($field));
                } )*
                None
            }
        }
        #[cfg(feature = "std")]
        impl $crate::filters::Params for $name {
            fn info() -> &'static [$crate::filters::ParamInfo] {
                Self::INFO
            }
            fn get(&self, name: &str) -> Option<f64> {
                match name { $( stringify!($field) => Some($crate::filters::ParamValue::to_f64(self.$field)), )* _ => None }
            }
            fn set(&mut self, name: &str, value: f64) -> Result<(), $crate::filters::ParamError> {
                match name {
                    $( stringify!($field) => {
                        if !($min..=$max).contains(&value) {
                            return Err($crate::filters::ParamError::OutOfRange { name: stringify!($field), value, min: $min, max: $max, unit: $unit });
                        }
                        self.$field = <$ty as $crate::filters::ParamValue>::from_f64(value).ok_or(
                            $crate::filters::ParamError::WrongKind {
                                name: stringify!($field), value, kind: <$ty as $crate::filters::ParamValue>::KIND,
                            },
                        )?;
                        Ok(())
                    } )*
                    _ => Err($crate::filters::ParamError::Unknown {
                        name: name.into(),
                        valid: <Self as $crate::filters::Params>::info().iter().map(|p| p.name).collect(),
                    }),
                }
            }
        }
    };
}
pub(crate) use params_with_screening;

#[cfg(test)]
mod tests {
    use crate::filters::{
        Dof, GyroParams, LaneParams, LaneParamsError, MahonyParams, SqrtEskf, SqrtEskfParams,
    };

    /// `validate` and `try_new` work in the no_std build too (`cargo test -p
    /// rootfuse-attitude --no-default-features --lib`): a struct literal out of range or NaN
    /// is refused, naming the parameter; the defaults pass.
    #[test]
    fn struct_literals_are_validated_without_std() {
        let bad = SqrtEskfParams {
            tau_acc: -1.0,
            ..SqrtEskfParams::default()
        };
        assert_eq!(bad.validate().map_err(|e| e.name), Err("tau_acc"));
        assert!(SqrtEskf::<f32>::try_new(&bad).is_err());
        let nan = MahonyParams {
            max_gyr: f64::NAN,
            ..MahonyParams::default()
        };
        assert_eq!(nan.validate().map_err(|e| e.name), Err("max_gyr"));
        assert_eq!(SqrtEskfParams::default().validate(), Ok(()));
        assert_eq!(GyroParams::default().validate(), Ok(()));
    }

    /// `LaneParams::per_lane` (no_std too) takes one set or one per lane, each in range and
    /// agreeing with set 0 on every shared parameter; the error names the lane and the key.
    #[test]
    fn per_lane_sets_are_refused_where_lanes_cannot_follow_them() {
        type Lanes = rootfuse_lane::wide::f32x8;
        let base = SqrtEskfParams::default();
        let sets = |change: &dyn Fn(&mut SqrtEskfParams)| {
            let mut sets = [(); 8].map(|_| base.clone());
            change(&mut sets[6]);
            sets
        };
        let per_lane = |sets: &[SqrtEskfParams]| LaneParams::<_, Lanes>::per_lane(sets).map(|_| ());
        // Real parameters vary per lane.
        assert_eq!(per_lane(&sets(&|p| p.gyr_noise *= 2.0)), Ok(()));
        assert_eq!(per_lane(&sets(&|p| p.tau_acc = 0.0)), Ok(()));
        assert_eq!(per_lane(core::slice::from_ref(&base)), Ok(()));
        // Structural ones do not: dof, switches, screening limits.
        for (change, name) in [
            (
                &(|p: &mut SqrtEskfParams| p.dof = Dof::Six) as &dyn Fn(&mut SqrtEskfParams),
                "dof",
            ),
            (&|p: &mut SqrtEskfParams| p.max_dt *= 2.0, "max_dt"),
            (&|p: &mut SqrtEskfParams| p.max_gyr *= 2.0, "max_gyr"),
            (&|p: &mut SqrtEskfParams| p.max_acc *= 2.0, "max_acc"),
        ] {
            let refused = per_lane(&sets(change));
            assert_eq!(refused, Err(LaneParamsError::Structural { lane: 6, name }));
        }
        let invalid = per_lane(&sets(&|p| p.gyr_noise = -1.0));
        assert!(
            matches!(invalid, Err(LaneParamsError::Invalid { lane: 6, error }) if error.name == "gyr_noise")
        );
        // Neither one set nor one per lane: refused, never wrapped or cut.
        for n in [0, 2, 3, 7, 9, 16] {
            let many = [(); 16].map(|_| base.clone());
            let refused = per_lane(&many[..n]);
            assert_eq!(refused, Err(LaneParamsError::Count { sets: n, lanes: 8 }));
        }
    }
}
