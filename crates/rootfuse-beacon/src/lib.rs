//! Heading and position from iBeacon RSSI, fused into the MEMS heading of the
//! `heading-pipeline` filter (std only, `f64`).
//!
//! Depends on `rootfuse-attitude` (the heading pipeline filter, quaternions), `rootfuse-lsq`
//! with `std` (the weighted batch solver on `faer` that fits the RSSI model and
//! multilaterates) and `rand*` (the seeded walk simulator). It is its own crate so that the
//! attitude core does not pull in `faer`.
//!
//! - [`model`]: the log-distance RSSI model `RSSI(d) = A − 10·n·log10(d)`, fitted by weighted
//!   least squares.
//! - [`map`]: one-second scans reduced to per-beacon means, and the windowed [`BeaconMap`].
//! - [`heading`]: heading from weak beacons (RSSI trends) and from medium/strong beacons
//!   (multilateration, then the direction of travel of the fixes).
//! - [`fuse`]: the beacon heading fused into `ψ_MEMS`, and pedestrian dead reckoning.
//! - [`sim`]: a seeded simulator (beacons, a walk with turns, shadowing, scan gaps, IMU) and
//!   the 10-minute experiment whose results docs/accuracy.md reports.
//!
//! Positions are metres in a local east/north plane; headings are the project's yaw: rad,
//! counter-clockwise about up, 0 toward north (+y), so walking at heading `ψ` moves along
//! `(−sin ψ, cos ψ)`.

#![warn(missing_docs)]

pub mod fuse;
pub mod heading;
pub mod map;
pub mod model;
pub mod sim;

pub use map::{BeaconMap, Record, ScanMean, Scanner};
pub use model::LogDistanceModel;

/// A beacon identifier (iBeacon major/minor packed by the caller).
pub type BeaconId = u32;

/// Beacon class by transmit power (S41).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BeaconClass {
    /// Low power: heard only nearby; used for heading from RSSI trends.
    Weak,
    /// Medium power: ranged with the fitted model.
    Medium,
    /// High power: ranged with the fitted model.
    Strong,
}

impl BeaconClass {
    /// The class of a beacon whose RSSI at 1 m is `tx_power` dBm: strong at −65 dBm and
    /// above, medium from −75 dBm, weak below.
    ///
    /// Reading of the source: S41 classes beacons by transmit power without thresholds; these
    /// are ours (strong beacons then reach about 25 m, weak ones a few metres, at `n = 2`).
    pub fn from_tx_power(tx_power: f64) -> Self {
        if tx_power >= -65.0 {
            Self::Strong
        } else if tx_power >= -75.0 {
            Self::Medium
        } else {
            Self::Weak
        }
    }
}

/// A beacon with a known position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beacon {
    /// Identifier.
    pub id: BeaconId,
    /// Position `[east, north]`, m.
    pub position: [f64; 2],
    /// Nominal RSSI at 1 m, dBm.
    pub tx_power: f64,
    /// Class (from `tx_power`).
    pub class: BeaconClass,
}

impl Beacon {
    /// A beacon, classed by its transmit power.
    pub fn new(id: BeaconId, position: [f64; 2], tx_power: f64) -> Self {
        Self {
            id,
            position,
            tx_power,
            class: BeaconClass::from_tx_power(tx_power),
        }
    }
}

/// The known beacons (the deployment survey).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BeaconSet {
    beacons: std::vec::Vec<Beacon>,
}

impl BeaconSet {
    /// A set from a list; a later duplicate id replaces an earlier one.
    pub fn new(list: impl IntoIterator<Item = Beacon>) -> Self {
        let mut beacons: std::vec::Vec<Beacon> = std::vec::Vec::new();
        for b in list {
            match beacons.iter_mut().find(|x| x.id == b.id) {
                Some(x) => *x = b,
                None => beacons.push(b),
            }
        }
        Self { beacons }
    }
    /// The beacon of an id.
    pub fn get(&self, id: BeaconId) -> Option<&Beacon> {
        self.beacons.iter().find(|b| b.id == id)
    }
    /// Every beacon.
    pub fn iter(&self) -> impl Iterator<Item = &Beacon> {
        self.beacons.iter()
    }
}

/// One received advertisement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Which beacon.
    pub id: BeaconId,
    /// Received signal strength, dBm (negative).
    pub rssi: f64,
    /// Reception time, s.
    pub t: f64,
}

/// Why beacon data could not be used.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum BeaconError {
    /// The RSSI is NaN or infinite.
    #[error("beacon {id}: RSSI {rssi} is not finite")]
    NonFiniteRssi {
        /// Beacon id.
        id: BeaconId,
        /// The value.
        rssi: f64,
    },
    /// The time stamp is NaN or infinite.
    #[error("beacon {id}: time {t} is not finite")]
    NonFiniteTime {
        /// Beacon id.
        id: BeaconId,
        /// The value.
        t: f64,
    },
    /// The id is not in the [`BeaconSet`].
    #[error("beacon {0} is not in the beacon set")]
    UnknownBeacon(BeaconId),
    /// Too few usable observations for the estimate.
    #[error("{needed} usable observations needed, {found} given")]
    TooFew {
        /// How many are needed.
        needed: usize,
        /// How many there were.
        found: usize,
    },
    /// An iterative estimate did not converge to a plausible solution.
    #[error("no converged solution")]
    NoSolution,
    /// The least-squares problem failed (rank, non-finite input, …).
    #[error("least squares: {0}")]
    Lsq(std::string::String),
}

impl From<rootfuse_lsq::dense::LsqError> for BeaconError {
    fn from(e: rootfuse_lsq::dense::LsqError) -> Self {
        Self::Lsq(std::format!("{e}"))
    }
}
