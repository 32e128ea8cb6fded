//! `run --device-params FILE`: per-device filter parameters over the run's own.
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_columnar::DeviceParams;
use std::path::{Path, PathBuf};

/// The specs of the devices a parameter table names: the run's spec with the table's values
/// set over it (an empty cell keeps the run's value).
pub struct DeviceSpecs {
    /// The table.
    pub file: PathBuf,
    /// The devices as the fleet names them, in table order.
    pub labels: Vec<String>,
    /// `specs[i]` is the spec of `labels[i]`.
    pub specs: Vec<FilterSpec>,
}

impl DeviceSpecs {
    /// Reads `path` (CSV, Parquet or Arrow: `device`, then one column per parameter) over
    /// `base`. An error names the file, the line or row and the column.
    pub fn read(path: &Path, base: &FilterSpec) -> Result<Self, String> {
        let table = DeviceParams::read(path).map_err(|e| e.to_string())?;
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
        })
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
