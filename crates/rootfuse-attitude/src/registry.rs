//! The list of filters by CLI name, with their parameters: one list for the CLI, the batch
//! engine and the tests.
//!
//! ```
//! use rootfuse_attitude::registry::FilterSpec;
//! use rootfuse_attitude::{Dof, ImuSample, OrientationFilter, Vec3};
//!
//! let mut spec = FilterSpec::new("mahony").unwrap();
//! spec.set("kp=1.0").unwrap();
//! spec.set_dof(Dof::Six).unwrap();
//! assert!(spec.set("kp=abc").is_err());
//! let mut filter = spec.build::<f32>();
//! let sample = ImuSample::six_d(Vec3::zero(), Vec3::new(0.0, 0.0, 9.81));
//! filter.update(&sample, 0.01);
//! assert!((filter.quat().norm() - 1.0).abs() < 1e-6);
//! ```

use crate::filters::*;
use crate::{ImuSample, Quat, Vec3};
use core::fmt;
use rootfuse_lane::{Lane, Mat};
use std::string::{String, ToString};

/// Why a filter could not be selected or configured.
#[derive(Clone, Debug, PartialEq)]
pub enum RegistryError {
    /// No filter of that name; the valid names are listed.
    UnknownFilter {
        /// The name given.
        name: String,
        /// Every registered name.
        valid: &'static [&'static str],
    },
    /// A parameter override was rejected.
    Param(ParamError),
    /// `dof` was given to a filter without a 6D/9D choice (`gyro`: it never reads the
    /// magnetometer), where it would otherwise be ignored.
    NoDof {
        /// The filter's name.
        filter: &'static str,
        /// The filters that have a `dof` parameter.
        with_dof: std::vec::Vec<&'static str>,
    },
    /// An override given to [`FilterSpec::set_all`] was refused: how it was given (the
    /// option or column a user wrote) and why.
    Given {
        /// How the override was given ([`Assignment::source`]).
        source: String,
        /// Why it was refused.
        error: std::boxed::Box<RegistryError>,
    },
}

impl fmt::Display for RegistryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownFilter { name, valid } => {
                write!(f, "unknown filter `{name}`")?;
                let names = core::iter::once("flagship").chain(valid.iter().copied());
                if let Some(near) = nearest_name(name, names) {
                    write!(f, ": did you mean `{near}`?")?;
                }
                write!(
                    f,
                    " (valid: flagship, the same as sqrt-eskf; {})",
                    valid.join(", ")
                )
            }
            Self::Param(e) => e.fmt(f),
            Self::NoDof { filter, with_dof } => write!(
                f,
                "filter `{filter}` has no 6D/9D choice (no `dof` parameter); leave dof out, or choose a filter that has one: {}",
                with_dof.join(", ")
            ),
            Self::Given { source, error } => write!(f, "{source}: {error}"),
        }
    }
}
impl std::error::Error for RegistryError {}

/// The name among `names` that `given` is most likely a misspelling of: the same but for case,
/// or at most a third of its letters (at least one) away by edits.
fn nearest_name<'a>(given: &str, names: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let given = given.trim().to_ascii_lowercase();
    let limit = (given.chars().count() / 3).max(1);
    names
        .map(|n| (edit_distance(&given, n), n))
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, n)| n)
}

/// Levenshtein distance between `a` and `b`, by characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: std::vec::Vec<char> = b.chars().collect();
    let mut row: std::vec::Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitute = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitute.min(row[j] + 1).min(diagonal + 1);
        }
    }
    row[b.len()]
}
impl From<ParamError> for RegistryError {
    fn from(e: ParamError) -> Self {
        Self::Param(e)
    }
}

macro_rules! registry {
    ($( $variant:ident => $name:literal, $filter:ident, $params:ident, $doc:literal; )*) => {
        /// A registered filter.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum FilterKind {
            $( #[doc = $doc] $variant, )*
        }

        impl FilterKind {
            /// Every registered filter, in listing order.
            pub const ALL: &'static [FilterKind] = &[$(FilterKind::$variant),*];
            /// Every registered name.
            pub const NAMES: &'static [&'static str] = &[$($name),*];
            /// The CLI name.
            pub fn name(self) -> &'static str {
                match self { $(Self::$variant => $name,)* }
            }
            /// One line on what the filter is.
            pub fn description(self) -> &'static str {
                match self { $(Self::$variant => $doc,)* }
            }
            /// The filter's parameters.
            pub fn params(self) -> &'static [ParamInfo] {
                match self { $(Self::$variant => $params::INFO,)* }
            }
            /// The filter of a CLI name.
            pub fn from_name(name: &str) -> Result<Self, RegistryError> {
                match name {
                    // The flagship filter is also accepted under its role name.
                    "flagship" => Ok(Self::SqrtEskf),
                    $($name => Ok(Self::$variant),)*
                    _ => Err(RegistryError::UnknownFilter { name: name.to_string(), valid: Self::NAMES }),
                }
            }
        }

        /// The parameters of one registered filter.
        // Built once per filter or spec, never per sample: boxing the flagship's set would
        // cost an allocation for nothing.
        #[allow(clippy::large_enum_variant)]
        #[derive(Clone, Debug, PartialEq)]
        pub enum AnyParams {
            $( #[doc = $doc] $variant($params), )*
        }

        impl AnyParams {
            fn defaults(kind: FilterKind) -> Self {
                match kind { $(FilterKind::$variant => Self::$variant($params::default()),)* }
            }
            fn apply(&mut self, assignment: &str) -> Result<(), ParamError> {
                match self { $(Self::$variant(p) => p.apply(assignment),)* }
            }
            fn set(&mut self, name: &str, value: f64) -> Result<(), ParamError> {
                match self { $(Self::$variant(p) => p.set(name, value),)* }
            }
            fn get(&self, name: &str) -> Option<f64> {
                match self { $(Self::$variant(p) => p.get(name),)* }
            }
            fn screen_limits(&self) -> ScreenLimits {
                match self { $(Self::$variant(p) => p.screen_limits(),)* }
            }
            /// Both of one filter and agreeing on every shared parameter
            /// ([`ParamSet::structural_difference`]).
            fn same_structure(&self, other: &Self) -> bool {
                match (self, other) {
                    $((Self::$variant(a), Self::$variant(b)) => a.structural_difference(b).is_none(),)*
                    #[allow(unreachable_patterns)]
                    _ => false,
                }
            }
        }

        /// Any registered filter over lanes of type `T`: what the CLI and the batch engine run.
        #[derive(Clone, Debug)]
        pub enum AnyFilter<T: Lane> {
            $( #[doc = $doc] $variant($filter<T>), )*
        }

        impl<T: Lane> AnyFilter<T> {
            fn build(params: &AnyParams) -> Self {
                match params { $(AnyParams::$variant(p) => Self::$variant($filter::new(p)),)* }
            }
        }

        impl<T: Lane> OrientationFilter<T> for AnyFilter<T> {
            #[inline]
            fn update(&mut self, sample: &ImuSample<T>, dt: T) {
                match self { $(Self::$variant(f) => f.update(sample, dt),)* }
            }
            #[inline]
            fn quat(&self) -> Quat<T> {
                match self { $(Self::$variant(f) => f.quat(),)* }
            }
            #[inline]
            fn bias(&self) -> Vec3<T> {
                match self { $(Self::$variant(f) => f.bias(),)* }
            }
            fn gyro_scale(&self) -> Vec3<T> {
                match self { $(Self::$variant(f) => f.gyro_scale(),)* }
            }
            #[inline]
            fn rejections(&self) -> &Rejections<T> {
                match self { $(Self::$variant(f) => f.rejections(),)* }
            }
            fn reset(&mut self) {
                match self { $(Self::$variant(f) => f.reset(),)* }
            }
            fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
                match self { $(Self::$variant(f) => f.set_quat(q, sigma),)* }
            }
            fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
                match self { $(Self::$variant(f) => f.set_bias(bias, sigma),)* }
            }
            #[inline]
            fn flags(&self) -> SampleFlags<T> {
                match self { $(Self::$variant(f) => f.flags(),)* }
            }
            #[inline]
            fn attitude_covariance(&self) -> Option<Mat<T, 3, 3>> {
                match self { $(Self::$variant(f) => OrientationFilter::attitude_covariance(f),)* }
            }
            #[inline]
            fn rest_detected(&self) -> Option<T::Mask> {
                match self { $(Self::$variant(f) => f.rest_detected(),)* }
            }
            fn smoothing_gyro_tau(&self) -> f64 {
                match self { $(Self::$variant(f) => f.smoothing_gyro_tau(),)* }
            }
            #[inline]
            fn magnetic_disturbance(&self) -> Option<T::Mask> {
                match self { $(Self::$variant(f) => f.magnetic_disturbance(),)* }
            }
            fn forget_field_reference(&mut self, lanes: T::Mask) {
                match self { $(Self::$variant(f) => f.forget_field_reference(lanes),)* }
            }
        }

        impl<T: Lane> FromSpec<T> for AnyFilter<T> {
            fn from_spec(spec: &FilterSpec) -> Option<Self> {
                Some(spec.build())
            }
            fn from_lane_specs(specs: &[&FilterSpec]) -> Option<Self> {
                match specs.first()?.kind {
                    $(FilterKind::$variant => {
                        <$filter<T> as FromSpec<T>>::from_lane_specs(specs).map(Self::$variant)
                    })*
                }
            }
        }

        $(
            impl<T: Lane> FromSpec<T> for $filter<T> {
                fn from_spec(spec: &FilterSpec) -> Option<Self> {
                    match &spec.params {
                        AnyParams::$variant(p) => Some($filter::new(p)),
                        #[allow(unreachable_patterns)]
                        _ => None,
                    }
                }
                fn from_lane_specs(specs: &[&FilterSpec]) -> Option<Self> {
                    let first = specs.first()?;
                    let sets = specs
                        .iter()
                        .map(|s| match &s.params {
                            AnyParams::$variant(p) if s.same_structure(first) => Some(p.clone()),
                            #[allow(unreachable_patterns)]
                            _ => None,
                        })
                        .collect::<Option<std::vec::Vec<$params>>>()?;
                    // A chunk's last lanes may have no channel: they run set 0, unread.
                    let mut sets = sets;
                    if let [first, _, ..] = sets.as_slice() && sets.len() < T::LANES {
                        let pad = first.clone();
                        sets.resize(T::LANES, pad);
                    }
                    Some($filter::with_lane_params(&LaneParams::per_lane(&sets).ok()?))
                }
            }
        )*

        $(
            impl TryFrom<$params> for FilterSpec {
                type Error = InvalidParam;
                /// The spec of this parameter struct's filter, after
                /// [`validate`]($params::validate).
                fn try_from(params: $params) -> Result<Self, InvalidParam> {
                    params.validate()?;
                    Ok(Self { kind: FilterKind::$variant, params: AnyParams::$variant(params) })
                }
            }
        )*

        impl FilterSpec {
            /// Calls `visitor` with this spec's concrete filter type over lanes `T`: one
            /// dispatch, after which everything runs on the concrete type (no enum match per
            /// sample, and state sized for this filter, not for the largest one).
            pub fn visit<T: Lane, V: FilterVisitor<T>>(&self, visitor: V) -> V::Output {
                match self.kind { $(FilterKind::$variant => visitor.visit::<$filter<T>>(self),)* }
            }
        }
    };
}

/// A filter type that can be built from a [`FilterSpec`] of its own kind.
pub trait FromSpec<T: Lane>: Sized {
    /// A fresh filter with the spec's parameters, or `None` when the spec is of another
    /// filter (always `Some` for [`AnyFilter`]).
    fn from_spec(spec: &FilterSpec) -> Option<Self>;
    /// A fresh filter whose lane `i` has the parameters of `specs[i % specs.len()]`; `None`
    /// when `specs` is empty, a spec is of another filter, or the specs differ in a parameter
    /// that cannot vary per lane ([`FilterSpec::same_structure`]). Lane `i` then computes
    /// exactly what a scalar filter built from `specs[i]` computes.
    fn from_lane_specs(specs: &[&FilterSpec]) -> Option<Self>;
}

/// The bounds every registered filter type meets, as [`FilterVisitor::visit`] hands it over.
pub trait RegisteredFilter<T: Lane>:
    OrientationFilter<T> + FromSpec<T> + Clone + fmt::Debug + Send + Sync + 'static
{
}
impl<T: Lane, F> RegisteredFilter<T> for F where
    F: OrientationFilter<T> + FromSpec<T> + Clone + fmt::Debug + Send + Sync + 'static
{
}

/// Code generic over the concrete filter type, run by [`FilterSpec::visit`].
///
/// ```
/// use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
///
/// struct StateBytes;
/// impl FilterVisitor<f32> for StateBytes {
///     type Output = usize;
///     fn visit<F: RegisteredFilter<f32>>(self, _: &FilterSpec) -> usize {
///         core::mem::size_of::<F>()
///     }
/// }
/// let spec = FilterSpec::new("mahony").unwrap();
/// assert!(spec.visit(StateBytes) < core::mem::size_of::<rootfuse_attitude::registry::AnyFilter<f32>>());
/// ```
pub trait FilterVisitor<T: Lane> {
    /// What the visit returns.
    type Output;
    /// Runs with `F`, the spec's concrete filter type (`F::from_spec(spec)` is `Some`).
    fn visit<F: RegisteredFilter<T>>(self, spec: &FilterSpec) -> Self::Output;
}

registry! {
    Gyro => "gyro", GyroIntegration, GyroParams, "Gyro-only integration by the exponential map (the drift reference).";
    Complementary => "complementary", Complementary, ComplementaryParams, "Quaternion complementary filter, decoupled inclination and heading corrections.";
    Mahony => "mahony", Mahony, MahonyParams, "Mahony explicit complementary filter with bias integral.";
    Madgwick => "madgwick", Madgwick, MadgwickParams, "Madgwick gradient-descent filter with the correct magnetic reference.";
    Ekf => "ekf", Ekf, EkfParams, "7-state quaternion + gyro-bias EKF (the plain EKF reference).";
    SqrtEskf => "sqrt-eskf", SqrtEskf, SqrtEskfParams, "Flagship: square-root error-state KF, decoupled heading, rest/bias, magnetic rejection (alias `flagship`).";
    EcfEkf => "ecf-ekf", EcfEkf, EcfEkfParams, "Patent method: moving average, Mahony ECF with magnetometer, 7-state EKF observing the ECF quaternion.";
    ComplementaryReconstruction => "complementary-reconstruction", ComplementaryReconstruction, ComplementaryReconstructionParams, "Patent method: rotation-vector gyro update blended with the acc/mag quaternion by the motion parameter α.";
    LsqFusion => "lsq-fusion", LsqFusion, LsqFusionParams, "Patent method: LS quaternion fusion, gyro denoising by forgetting-factor LS, square-root RLS drift.";
    HeadingPipeline => "heading-pipeline", HeadingPipeline, HeadingPipelineParams, "Patent method, MEMS heading: smoothed accelerometer inclination, 2-state heading/bias Kalman filter, 0.96 circular blend, declination.";
}

/// One `key=value` override with the words that gave it, for [`FilterSpec::set_all`]: an
/// error about it quotes [`source`](Self::source), so that a user reads the option or the
/// column they wrote rather than a reconstructed assignment.
///
/// ```
/// use rootfuse_attitude::registry::{Assignment, FilterSpec};
///
/// let mut spec = FilterSpec::new("mahony").unwrap();
/// let err = spec
///     .set_all(&[
///         Assignment::from_source("max_dt=2", "--max-dt 2"),
///         Assignment::from_source("max_dt=3", "--param max_dt=3"),
///     ])
///     .unwrap_err();
/// assert_eq!(
///     err.to_string(),
///     "`max_dt` is given twice: by --max-dt 2 and by --param max_dt=3; give it once"
/// );
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Assignment {
    /// `key=value`, as [`FilterSpec::set`] takes it.
    pub text: String,
    /// How it was given (`--param kp=1`, `--dof 6`, `column kp`): named in errors.
    pub source: String,
}

impl Assignment {
    /// An override whose errors name it by its own text.
    pub fn new(text: impl Into<String>) -> Self {
        let text = text.into();
        Self {
            source: text.clone(),
            text,
        }
    }
    /// An override whose errors name it by `source`, the option or column that gave it.
    pub fn from_source(text: impl Into<String>, source: impl Into<String>) -> Self {
        Self {
            text: text.into(),
            source: source.into(),
        }
    }
    /// The parameter name, or `None` when the text is not of the form `key=value`.
    fn key(&self) -> Option<&str> {
        self.text.split_once('=').map(|(k, _)| k.trim())
    }
}

/// A filter choice with its parameter values: build it for any lane type.
///
/// Made by name with `key=value` overrides ([`new`](Self::new), [`set`](Self::set)), or from
/// a typed parameter struct (`TryFrom`, validated), which is how typed parameters reach the
/// batch engine:
///
/// ```
/// use rootfuse_attitude::filters::{MahonyParams, SqrtEskfParams};
/// use rootfuse_attitude::registry::{FilterKind, FilterSpec};
///
/// let typed = SqrtEskfParams { tau_acc: 1.0, ..Default::default() };
/// let spec = FilterSpec::try_from(typed).unwrap();
/// assert_eq!(spec.kind(), FilterKind::SqrtEskf);
/// assert_eq!(spec.get("tau_acc"), Some(1.0));
/// let refused = FilterSpec::try_from(MahonyParams { kp: -1.0, ..Default::default() });
/// assert_eq!(refused.unwrap_err().name, "kp");
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct FilterSpec {
    kind: FilterKind,
    params: AnyParams,
}

impl FilterSpec {
    /// The named filter with default parameters.
    pub fn new(name: &str) -> Result<Self, RegistryError> {
        let kind = FilterKind::from_name(name)?;
        Ok(Self {
            kind,
            params: AnyParams::defaults(kind),
        })
    }
    /// Which filter.
    pub fn kind(&self) -> FilterKind {
        self.kind
    }
    /// Applies a `key=value` override (validated). `dof` for a filter without one (`gyro`)
    /// is [`RegistryError::NoDof`]: asking for 6D or 9D there is a mistake worth hearing of.
    pub fn set(&mut self, assignment: &str) -> Result<(), RegistryError> {
        if Assignment::new(assignment).key() == Some("dof") && self.dof().is_none() {
            return Err(RegistryError::NoDof {
                filter: self.kind.name(),
                with_dof: FilterKind::ALL
                    .iter()
                    .filter(|k| k.params().iter().any(|p| p.name == "dof"))
                    .map(|k| k.name())
                    .collect(),
            });
        }
        Ok(self.params.apply(assignment)?)
    }
    /// Applies several overrides, each parameter at most once: a parameter given twice (even
    /// with the same value) is [`ParamError::Repeated`] naming both sources, so that neither
    /// silently wins. Any other refusal is [`RegistryError::Given`], naming the source. All
    /// or nothing: after an error the spec is as it was.
    pub fn set_all(&mut self, assignments: &[Assignment]) -> Result<(), RegistryError> {
        let mut next = self.clone();
        let mut seen: std::vec::Vec<(&str, &str)> = std::vec::Vec::new();
        for a in assignments {
            if let Some(key) = a.key() {
                if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
                    return Err(ParamError::Repeated {
                        name: key.to_string(),
                        first: first.to_string(),
                        second: a.source.clone(),
                    }
                    .into());
                }
                seen.push((key, &a.source));
            }
            next.set(&a.text).map_err(|e| RegistryError::Given {
                source: a.source.clone(),
                error: std::boxed::Box::new(e),
            })?;
        }
        *self = next;
        Ok(())
    }
    /// Selects 6D (no magnetometer) or 9D operation for filters that have a `dof` parameter
    /// and leaves `gyro` (none: it never reads the magnetometer) as it is: for code that
    /// runs every filter in 6D and 9D. A user's choice goes through [`set`](Self::set) or
    /// [`set_all`](Self::set_all) (`dof=6`), which refuse it for `gyro`.
    pub fn set_dof(&mut self, dof: Dof) -> Result<(), RegistryError> {
        if self.params.get("dof").is_some() {
            self.params.set("dof", dof.to_f64())?;
        }
        Ok(())
    }
    /// 6D or 9D for filters that have a `dof` parameter, `None` for `gyro`.
    pub fn dof(&self) -> Option<Dof> {
        self.params.get("dof").and_then(Dof::from_f64)
    }
    /// True when the filter reads the magnetometer (9D): the one answer for the CLI, the
    /// batch engine and the tests (`gyro`: false).
    pub fn uses_magnetometer(&self) -> bool {
        self.dof().is_some_and(Dof::uses_magnetometer)
    }
    /// True when `other` is the same filter and agrees with this spec on every parameter
    /// that cannot differ between the lanes of one SIMD chunk ([`ParamInfo::per_lane`]
    /// false: `dof`, switches, whole numbers, screening limits, `shared` ones): the two can
    /// then run in lanes of one chunk, each with its own per-lane parameters.
    pub fn same_structure(&self, other: &FilterSpec) -> bool {
        self.params.same_structure(&other.params)
    }
    /// The input-screening limits (`max_dt`, `max_gyr`, `max_acc`, `max_mag`) these
    /// parameters give the filter.
    pub fn screen_limits(&self) -> ScreenLimits {
        self.params.screen_limits()
    }
    /// The current value of a parameter.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.params.get(name)
    }
    /// The parameters.
    pub fn params(&self) -> &AnyParams {
        &self.params
    }
    /// The spec each pass of the offline smoother ([`crate::smooth::forward_backward`])
    /// builds: for `sqrt-eskf` [`SqrtEskfParams::for_smoothing`], for the other filters this
    /// spec unchanged.
    pub fn for_smoothing(&self) -> Self {
        let mut spec = self.clone();
        if let AnyParams::SqrtEskf(p) = &self.params {
            spec.params = AnyParams::SqrtEskf(p.for_smoothing());
        }
        spec
    }
    /// A fresh filter over lanes of type `T` with these parameters.
    pub fn build<T: Lane>(&self) -> AnyFilter<T> {
        AnyFilter::build(&self.params)
    }
}
