//! `run --device-params FILE`: per-device filter parameters over the run's own.
use rootfuse_attitude::registry::{Assignment, FilterSpec};
use rootfuse_columnar::DeviceParams;
use std::path::{Path, PathBuf};

/// The specs of the devices a parameter table names: the run's spec with the table's values
/// set over it (an empty cell keeps the run's value). A table column that the command line
/// also sets is that precedence, not a conflict: the table is the per-device exception to
/// the run's values, and [`overrides`](Self::overrides) says so aloud.
pub struct DeviceSpecs {
    /// The table.
    pub file: PathBuf,
    /// The devices as the fleet names them, in table order.
    pub labels: Vec<String>,
    /// `specs[i]` is the spec of `labels[i]`.
    pub specs: Vec<FilterSpec>,
    /// The columns that the command line also sets: `(column, how the command line set it,
    /// devices with a value in that column)`.
    overridden: Vec<(String, String, usize)>,
}

impl DeviceSpecs {
    /// Reads `path` (CSV, Parquet or Arrow: `device`, then one column per parameter) over
    /// `base`, the spec the command line's `given` parameters made. An error names the file,
    /// the line or row and the column.
    pub fn read(path: &Path, base: &FilterSpec, given: &[Assignment]) -> Result<Self, String> {
        let table = DeviceParams::read(path).map_err(|e| e.to_string())?;
        let overridden = table
            .names
            .iter()
            .enumerate()
            .filter_map(|(c, name)| {
                let source = given.iter().find(|a| {
                    a.text
                        .split_once('=')
                        .is_some_and(|(k, _)| k.trim() == name)
                })?;
                let devices = table.rows.iter().filter(|r| r.values[c].is_some()).count();
                Some((name.clone(), source.source.clone(), devices))
            })
            .collect();
        let mut labels = Vec::with_capacity(table.rows.len());
        let mut specs = Vec::with_capacity(table.rows.len());
        for row in &table.rows {
            let mut spec = base.clone();
            for (name, value) in table.names.iter().zip(&row.values) {
                if let Some(v) = value {
                    // `{:?}` is the shortest text that parses back to the same f64.
                    spec.set(&format!("{name}={v:?}")).map_err(|e| {
                        format!(
                            "{}: {}, column `{name}`: {e} (device {})",
                            path.display(),
                            row.place,
                            row.device
                        )
                    })?;
                }
            }
            labels.push(row.device.clone());
            specs.push(spec);
        }
        Ok(Self {
            file: path.to_owned(),
            labels,
            specs,
            overridden,
        })
    }

    /// One note per table column that the command line also sets: which value each device
    /// runs with.
    pub fn overrides(&self) -> Vec<String> {
        self.overridden
            .iter()
            .map(|(column, source, devices)| {
                format!(
                    "note: --device-params {}: column `{column}` is set over {source} for the {devices} device(s) with a value in it; the others run with {source}",
                    self.file.display()
                )
            })
            .collect()
    }

    /// The spec of the device `label`, if the table names it.
    pub fn get(&self, label: &str) -> Option<&FilterSpec> {
        self.labels
            .iter()
            .position(|l| l == label)
            .map(|i| &self.specs[i])
    }

    /// The notes a run prints: how many devices ran with the defaults, and which devices of
    /// the table had no rows.
    pub fn report(&self, with_defaults: usize, unseen: &[&str]) {
        eprintln!(
            "note: --device-params {}: {} device(s) with parameters of their own, {with_defaults} device(s) not in it ran with the run's parameters",
            self.file.display(),
            self.labels.len() - unseen.len(),
        );
        if !unseen.is_empty() {
            eprintln!(
                "note: --device-params {}: {} device(s) of the table had no rows: {}",
                self.file.display(),
                unseen.len(),
                unseen.join(", ")
            );
        }
    }
}
