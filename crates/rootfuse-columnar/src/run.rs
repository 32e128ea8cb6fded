//! [`FleetBlocks`]: a fleet reader's blocks run one at a time through a
//! [`FleetRunner`], with the one block of lookahead the runner needs.

use crate::error::ColumnarError;
use crate::reader::{Devices, FleetChunk, FleetReader};
use rootfuse_batch::{BlockEstimates, FleetError, FleetRunner, OnError};

/// Runs the blocks of a [`FleetReader`] through a [`FleetRunner`] one at a time: what the
/// CLI's `run` does for a Parquet or Arrow file and what the Python package does for an
/// Arrow stream, written once.
///
/// Each call of [`next_block`](Self::next_block) reads the block after the one it runs, so
/// that a device whose first row ends a block gets its first step from the next block (see
/// [`FleetRunner`]), and returns the block run with its estimates.
#[derive(Debug, Default)]
pub struct FleetBlocks {
    current: Option<FleetChunk>,
    primed: bool,
}

impl FleetBlocks {
    /// Before the first block.
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads, prepares (for example calibrates: `prepare` may change the sensor values, not
    /// the devices or times) and runs the next block of `reader`; `None` after the last one.
    /// A bad row stops the run with an error naming the file, part, row and device
    /// ([`ColumnarError::Time`]), or with [`OnError::DropDevice`] drops that device (listed
    /// in [`BlockEstimates::failures`]; [`locate`](Self::locate) names the row).
    pub fn next_block(
        &mut self,
        reader: &mut FleetReader,
        devices: &mut Devices,
        runner: &mut FleetRunner,
        on_error: OnError,
        prepare: impl FnOnce(&mut FleetChunk),
    ) -> Result<Option<(FleetChunk, BlockEstimates)>, ColumnarError> {
        if !self.primed {
            self.current = reader.next_chunk(devices)?;
            self.primed = true;
        }
        let Some(mut chunk) = self.current.take() else {
            return Ok(None);
        };
        prepare(&mut chunk);
        let next = reader.next_chunk(devices)?;
        let est = runner
            .step(&chunk.block, next.as_ref().map(|c| &c.block), on_error)
            .map_err(|e| Self::locate(reader, &chunk, devices, e))?;
        self.current = next;
        Ok(Some((chunk, est)))
    }

    /// A fleet error of a block as a [`ColumnarError::Time`] naming the file, part, file
    /// row and device.
    pub fn locate(
        reader: &FleetReader,
        chunk: &FleetChunk,
        devices: &Devices,
        e: FleetError,
    ) -> ColumnarError {
        ColumnarError::Time {
            file: reader.path().to_owned(),
            part: chunk.part,
            row: chunk.first_row + e.row() as u64,
            device: devices.label(e.device()).to_string(),
            source: e,
            // Time restarting in a file without a device column: several devices' rows.
            hint: if reader.device_type().is_none() {
                "; the file has no `device` column, so all its rows are one device: if it holds several, name each row's device in a `device` column"
            } else {
                ""
            },
        }
    }
}
