//! One-second scans and the windowed `BeaconMap` (S421–S424).

use super::{BeaconError, BeaconId, BeaconSet, Reading};
use std::collections::{BTreeMap, VecDeque};
use std::vec::Vec;

/// One beacon's result of a scan: mean RSSI and the last time it was heard (S422).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanMean {
    /// Beacon id.
    pub id: BeaconId,
    /// Mean RSSI over the scan, dBm.
    pub rssi: f64,
    /// Time of the last reading in the scan, s.
    pub last_seen: f64,
}

/// Collects the readings of one scan (S421): readings below `threshold` dBm are filtered out
/// (counted), bad readings are refused with a typed error (and counted).
#[derive(Clone, Debug)]
pub struct Scanner {
    threshold: f64,
    sums: BTreeMap<BeaconId, (f64, usize, f64)>,
    /// Readings refused as bad (non-finite RSSI or time, unknown id) since construction.
    pub bad: u64,
    /// Readings filtered out below the threshold since construction.
    pub below_threshold: u64,
}

impl Scanner {
    /// A scanner that ignores readings below `threshold` dBm.
    pub fn new(threshold: f64) -> Self {
        Self {
            threshold,
            sums: BTreeMap::new(),
            bad: 0,
            below_threshold: 0,
        }
    }
    /// Adds one reading of the current scan.
    ///
    /// # Errors
    /// [`BeaconError::NonFiniteRssi`], [`BeaconError::NonFiniteTime`],
    /// [`BeaconError::UnknownBeacon`] (the reading is skipped and counted in `bad`).
    pub fn add(&mut self, r: Reading, beacons: &BeaconSet) -> Result<(), BeaconError> {
        let err = if !r.rssi.is_finite() {
            Some(BeaconError::NonFiniteRssi {
                id: r.id,
                rssi: r.rssi,
            })
        } else if !r.t.is_finite() {
            Some(BeaconError::NonFiniteTime { id: r.id, t: r.t })
        } else if beacons.get(r.id).is_none() {
            Some(BeaconError::UnknownBeacon(r.id))
        } else {
            None
        };
        if let Some(e) = err {
            self.bad += 1;
            return Err(e);
        }
        if r.rssi < self.threshold {
            self.below_threshold += 1;
            return Ok(());
        }
        let e = self.sums.entry(r.id).or_insert((0.0, 0, r.t));
        e.0 += r.rssi;
        e.1 += 1;
        e.2 = e.2.max(r.t);
        Ok(())
    }
    /// Ends the scan: the per-beacon means (in id order), and a fresh scan begins.
    pub fn finish(&mut self) -> Vec<ScanMean> {
        let out = self
            .sums
            .iter()
            .map(|(&id, &(sum, n, last))| ScanMean {
                id,
                rssi: sum / n as f64,
                last_seen: last,
            })
            .collect();
        self.sums.clear();
        out
    }
}

/// One record of the map: a scan mean (dBm), or 0 when the beacon was not heard in that scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// Mean RSSI, dBm; exactly 0 for "not heard".
    pub rssi: f64,
    /// Last-seen time of the scan mean, or the scan time for a 0 record, s.
    pub t: f64,
}

impl Record {
    /// True for a "not heard" record.
    pub fn missed(&self) -> bool {
        self.rssi == 0.0
    }
}

/// The `BeaconMap` (S423–S424): for each beacon heard since the last clear, its last `T`
/// records, one per scan.
///
/// Rules, applied by [`push_scan`](Self::push_scan) once per scan:
/// - a beacon in the scan gets its mean appended; a new beacon gets a new entry;
/// - a beacon in the map but not in the scan gets a 0 record at the scan time;
/// - an entry longer than `T` records drops its oldest record.
///
/// [`clear`](Self::clear) empties the map; the heading algorithms call it once a heading is
/// decided (S424, claim 7).
///
/// Reading of the source: S423 speaks of a window of `T` seconds and S424 of `T` records;
/// with one scan per second these agree, and the window is kept as a record count.
#[derive(Clone, Debug)]
pub struct BeaconMap {
    capacity: usize,
    entries: BTreeMap<BeaconId, VecDeque<Record>>,
}

impl BeaconMap {
    /// A map keeping `capacity` (`T ≥ 1`) records per beacon.
    pub fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            entries: BTreeMap::new(),
        }
    }
    /// Records per beacon kept.
    pub fn capacity(&self) -> usize {
        self.capacity
    }
    /// Applies one scan's means taken at time `t` (s).
    pub fn push_scan(&mut self, t: f64, means: &[ScanMean]) {
        for m in means {
            self.entries.entry(m.id).or_default().push_back(Record {
                rssi: m.rssi,
                t: m.last_seen,
            });
        }
        for (id, records) in self.entries.iter_mut() {
            if !means.iter().any(|m| m.id == *id) {
                records.push_back(Record { rssi: 0.0, t });
            }
            while records.len() > self.capacity {
                records.pop_front();
            }
        }
    }
    /// The records of a beacon, oldest first.
    pub fn records(&self, id: BeaconId) -> Option<&VecDeque<Record>> {
        self.entries.get(&id)
    }
    /// Every beacon with its records, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (BeaconId, &VecDeque<Record>)> {
        self.entries.iter().map(|(id, r)| (*id, r))
    }
    /// Number of beacons in the map.
    pub fn len(&self) -> usize {
        self.entries.len()
    }
    /// True when no beacon is in the map.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
    /// Empties the map (after a heading decision).
    pub fn clear(&mut self) {
        self.entries.clear();
    }
}
