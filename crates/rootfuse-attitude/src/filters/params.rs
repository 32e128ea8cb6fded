//! Named, validated filter parameters (`key=value` overrides), shared by the CLI, the batch
//! engine and the tests.

#[cfg(feature = "std")]
use core::fmt;

/// One parameter's description.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamInfo {
    /// Name used in `key=value`.
    pub name: &'static str,
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
    },
    /// Not of the form `key=value`.
    Syntax(std::string::String),
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
            } => {
                write!(f, "parameter `{name}` = {value} is outside [{min}, {max}]")
            }
            Self::Syntax(text) => write!(f, "`{text}` is not of the form key=value"),
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

/// Declares a parameter struct: fields are `f64`, each with default, unit, range and doc.
macro_rules! params {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[doc = $fdoc:literal])* $field:ident: $default:expr, $unit:literal, [$min:expr, $max:expr]; )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name {
            $( $(#[doc = $fdoc])* #[doc = concat!("\n\nUnit: ", $unit, ". Default: ", stringify!($default), ".")] pub $field: f64, )*
        }
        impl Default for $name {
            fn default() -> Self {
                Self { $( $field: $default, )* }
            }
        }
        impl $name {
            /// Every parameter with its default, unit, range and description.
            pub const INFO: &'static [$crate::filters::ParamInfo] = &[ $( $crate::filters::ParamInfo {
                name: stringify!($field), default: $default, unit: $unit, min: $min, max: $max,
                doc: concat!($($fdoc),*).trim_ascii(),
            }, )* ];
        }
        #[cfg(feature = "std")]
        impl $crate::filters::Params for $name {
            fn info() -> &'static [$crate::filters::ParamInfo] {
                Self::INFO
            }
            fn get(&self, name: &str) -> Option<f64> {
                match name { $( stringify!($field) => Some(self.$field), )* _ => None }
            }
            fn set(&mut self, name: &str, value: f64) -> Result<(), $crate::filters::ParamError> {
                match name {
                    $( stringify!($field) => {
                        if !($min..=$max).contains(&value) {
                            return Err($crate::filters::ParamError::OutOfRange { name: stringify!($field), value, min: $min, max: $max });
                        }
                        self.$field = value;
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
pub(crate) use params;
