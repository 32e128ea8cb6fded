//! `rootfuse run` streaming: inputs read, filtered and written a block of rows at a time, so
//! memory holds the filters' state and a few blocks, never a whole recording.
//!
//! CSV inputs are one device each and are read side by side (a block of every file per
//! step), so several files share the SIMD lanes as before. Parquet and Arrow inputs are one
//! fleet: read in order, their rows grouped by the `device` column (devices keep their
//! filters from one file to the next, so a folder of files split by time runs as one).
use crate::checks::InputChecks;
use crate::signal::{exit_interrupted, interrupted};
use rootfuse_attitude::OrientationFilter;
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::units::Units;
use rootfuse_batch::{Columns, FleetBlock, FleetRunner, OnError, Precision, RejectionTotals};
use rootfuse_columnar::{
    BLOCK_ROWS, ColumnarError, Devices, EstimateWriter, FleetBlocks, FleetChunk, FleetReader,
    Format, ImuGaps, Part, estimate_names,
};
use rootfuse_io::{CsvBlocks, Staged};
use std::path::{Path, PathBuf};

/// What the run asks for, shared by both input kinds.
pub struct Job<'a> {
    pub spec: &'a FilterSpec,
    pub precision: Precision,
    pub columns: Columns,
    pub format: Format,
    pub gaps: ImuGaps,
    /// `--units`: what the inputs are written in; `--strict`: unit findings are errors.
    pub units: Units,
    pub strict: bool,
    pub keep_going: bool,
    /// The filter uses the magnetometer; `dof_explicit`: the user asked for it.
    pub nine_d: bool,
    pub dof_explicit: bool,
    /// `--calibration`: applied to every block of raw readings before the filter sees it.
    pub calibration: Option<&'a crate::calibrate::CalibrationSet>,
    /// `--device-params`: the devices with parameters of their own.
    pub device_specs: Option<&'a crate::device_params::DeviceSpecs>,
}

impl Job<'_> {
    /// Applies `--calibration` (if any) to a block of raw readings.
    pub fn calibrate(&self, block: &mut FleetBlock) {
        if let Some(cal) = self.calibration {
            cal.apply(&mut block.gyr, &mut block.acc, block.mag.as_deref_mut());
        }
    }
}

/// Totals of a run, for the summary lines.
#[derive(Default)]
pub struct Totals {
    pub files: usize,
    /// Devices of a Parquet or Arrow fleet (0 for CSV recordings, one device each).
    pub devices: usize,
    pub failed_files: usize,
    pub failed_devices: usize,
    pub samples: u64,
    pub missing_imu: u64,
    pub files_with_missing_imu: usize,
    pub rejections: RejectionTotals,
}

impl Totals {
    /// Counts a file that could not be completed: reported under `--keep-going`, else the
    /// run's error.
    pub fn fail(&mut self, e: String, keep_going: bool) -> Result<(), String> {
        if !keep_going {
            return Err(e);
        }
        eprintln!("error: {e}");
        self.failed_files += 1;
        Ok(())
    }

    /// Counts a completed file's samples with missing IMU values.
    pub fn missing(&mut self, missing_imu: u64) {
        self.missing_imu += missing_imu;
        self.files_with_missing_imu += usize::from(missing_imu > 0);
    }
}

/// Refuses (explicit 9D) or notes (the filter's default) a file without magnetometer columns.
pub fn check_mag(job: &Job, file: &Path, has_mag: bool) -> Result<(), String> {
    if job.nine_d && !has_mag {
        let message = format!(
            "{}: no magnetometer columns (mx,my,mz) for 9D operation; use --dof 6",
            file.display()
        );
        if job.dof_explicit {
            return Err(message);
        }
        eprintln!(
            "note: {message} (the filter's default is 9D: every magnetometer correction is skipped)"
        );
    }
    Ok(())
}

/// One CSV input being streamed.
struct CsvInput {
    blocks: CsvBlocks<std::fs::File>,
    buffer: rootfuse_attitude::Recording,
    writer: EstimateWriter,
    device: u32,
    missing_imu: u64,
}

/// Estimate files complete under their temporary names, with their inputs: put in place by
/// the caller once every input has run (dropped, they are removed).
pub type StagedFiles = Vec<(PathBuf, Staged)>;

/// Streams CSV recordings side by side, `files[i]` estimated into `outs[i]` (staged).
pub fn run_csv(
    job: &Job,
    files: &[PathBuf],
    outs: &[PathBuf],
    staged: &mut StagedFiles,
) -> Result<Totals, String> {
    let mut totals = Totals::default();
    let file_specs = csv_file_specs(job, files);
    let mut runner = fleet_runner(job, &file_specs)?;
    let names = estimate_names(job.columns, runner_has_covariance(job));
    // A block of all files together stays about BLOCK_ROWS rows (at least 2 per file, so
    // that every file's first step is known from its first block).
    let rows_per_file = (BLOCK_ROWS / files.len().max(1)).max(256);
    let mut inputs: Vec<CsvInput> = Vec::new();
    for (i, (file, out)) in files.iter().zip(outs).enumerate() {
        let opened = open_csv_input(job, file, out, i as u32, rows_per_file, &names);
        match opened {
            Ok(input) => inputs.push(input),
            Err(e) => totals.fail(e, job.keep_going)?,
        }
    }
    if inputs.is_empty() {
        return Err("no input could be read".into());
    }
    let devices = Devices::default();
    let mut checks = InputChecks::new(job.units, job.strict);
    while !inputs.is_empty() {
        if interrupted() {
            // Dropping the writers and staged files removes their temporary files.
            drop(inputs);
            staged.clear();
            exit_interrupted();
        }
        let (mut block, ranges) = csv_block(&inputs);
        checks.observe(&block);
        job.calibrate(&mut block);
        // CSV rows were checked (time finite, increasing) by the reader already.
        let est = runner
            .step(&block, None, OnError::Stop)
            .map_err(|e| e.to_string())?;
        let chunk = FleetChunk {
            block,
            device_column: None,
            part: Part::Block,
            first_row: 0,
            missing_imu: 0,
        };
        let mut still = Vec::with_capacity(inputs.len());
        for (mut input, range) in inputs.into_iter().zip(ranges) {
            totals.samples += range.len() as u64;
            input.missing_imu += chunk.block.rows_with_missing_imu(range.clone()) as u64;
            let step = (|| -> Result<bool, String> {
                input
                    .writer
                    .write(&chunk, &devices, &est, range)
                    .map_err(|e| e.to_string())?;
                input.buffer = input.blocks.empty_recording();
                let read = input
                    .blocks
                    .read_into(&mut input.buffer, rows_per_file)
                    .map_err(|e| e.to_string())?;
                Ok(read > 0)
            })();
            match step {
                Ok(true) => still.push(input),
                Ok(false) => {
                    let file = files[input.device as usize].clone();
                    let rejections = runner.rejections(input.device);
                    let nine_d = job.nine_d && input.blocks.has_mag();
                    let verdict = checks.judge(
                        &file.display().to_string(),
                        input.device,
                        rejections,
                        nine_d,
                    );
                    for w in &verdict.warnings {
                        eprintln!("warning: {w}");
                    }
                    if let Some(e) = verdict.error {
                        // The writer dropped removes the estimate in progress.
                        totals.fail(e, job.keep_going)?;
                        continue;
                    }
                    staged.push((file, input.writer.close().map_err(|e| e.to_string())?));
                    totals.files += 1;
                    totals.rejections += rejections;
                    totals.missing(input.missing_imu);
                }
                Err(e) => totals.fail(e, job.keep_going)?,
            }
        }
        inputs = still;
    }
    Ok(totals)
}

/// The filter of each CSV file under `--device-params` (file `i` is device `i`, named after
/// its stem; none without a table), after reporting the table's rows and files that did not
/// meet.
fn csv_file_specs(job: &Job, files: &[PathBuf]) -> Vec<FilterSpec> {
    // File `i` is device `i`, named after its stem: with `--device-params` every file gets
    // its spec up front (the table's, or the run's).
    let file_specs: Vec<FilterSpec> = match job.device_specs {
        Some(table) => files
            .iter()
            .map(|f| {
                let stem = f
                    .file_stem()
                    .map(|s| s.to_string_lossy())
                    .unwrap_or_default();
                table.get(&stem).unwrap_or(job.spec).clone()
            })
            .collect(),
        None => Vec::new(),
    };
    if let Some(table) = job.device_specs {
        let stems: Vec<String> = files
            .iter()
            .map(|f| {
                f.file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default()
            })
            .collect();
        let unseen: Vec<&str> = table
            .labels
            .iter()
            .filter(|l| !stems.contains(l))
            .map(String::as_str)
            .collect();
        let listed = stems.iter().filter(|s| table.get(s).is_some()).count();
        table.report(files.len() - listed, &unseen);
    }
    file_specs
}

/// Opens CSV recording `file` as device `device`: its first block read (a file with only a
/// header is an error), the magnetometer checked against the run, the estimate writer created.
fn open_csv_input(
    job: &Job,
    file: &Path,
    out: &Path,
    device: u32,
    rows_per_file: usize,
    names: &[&str],
) -> Result<CsvInput, String> {
    let mut blocks = CsvBlocks::open(file, job.gaps)
        .map_err(|e| e.to_string())?
        .with_units(job.units);
    let mut buffer = blocks.empty_recording();
    if blocks
        .read_into(&mut buffer, rows_per_file)
        .map_err(|e| e.to_string())?
        == 0
    {
        return Err(format!(
            "{}: line 2: no data rows (the file has only a header)",
            file.display()
        ));
    }
    check_mag(job, file, blocks.has_mag())?;
    let writer = EstimateWriter::create(out, job.format, None, names).map_err(|e| e.to_string())?;
    Ok(CsvInput {
        blocks,
        buffer,
        writer,
        device,
        missing_imu: 0,
    })
}

/// Whether the estimate has covariance columns: the filter must carry one.
fn runner_has_covariance(job: &Job) -> bool {
    job.columns.covariance && job.spec.build::<f64>().attitude_covariance().is_some()
}

/// The buffered rows of every input as one block, with each input's row range in it.
fn csv_block(inputs: &[CsvInput]) -> (FleetBlock, Vec<std::ops::Range<usize>>) {
    let rows: usize = inputs.iter().map(|i| i.buffer.len()).sum();
    let any_mag = inputs.iter().any(|i| i.buffer.mag.is_some());
    let mut block = FleetBlock {
        device: Vec::with_capacity(rows),
        t: Vec::with_capacity(rows),
        gyr: Vec::with_capacity(rows),
        acc: Vec::with_capacity(rows),
        mag: any_mag.then(|| Vec::with_capacity(rows)),
    };
    let mut ranges = Vec::with_capacity(inputs.len());
    for input in inputs {
        let rec = &input.buffer;
        let start = block.len();
        block
            .device
            .extend(std::iter::repeat_n(input.device, rec.len()));
        block.t.extend(&rec.t);
        block.gyr.extend(&rec.gyr);
        block.acc.extend(&rec.acc);
        if let Some(mag) = &mut block.mag {
            // A 6D file among 9D ones: NaN field, exactly what a 6D sample carries.
            match &rec.mag {
                Some(m) => mag.extend(m),
                None => mag.extend(std::iter::repeat_n(
                    rootfuse_attitude::Vec3::new(f64::NAN, f64::NAN, f64::NAN),
                    rec.len(),
                )),
            }
        }
        ranges.push(start..block.len());
    }
    (block, ranges)
}

/// Streams Parquet/Arrow fleet files in order, `files[i]` estimated into `outs[i]` (staged).
pub fn run_columnar(
    job: &Job,
    files: &[PathBuf],
    outs: &[PathBuf],
    staged: &mut StagedFiles,
) -> Result<Totals, String> {
    let mut totals = Totals::default();
    let (labels, specs) = match job.device_specs {
        Some(table) => (table.labels.as_slice(), table.specs.as_slice()),
        None => (&[][..], &[][..]),
    };
    let mut runner = fleet_runner(job, specs)?;
    let names = estimate_names(job.columns, runner_has_covariance(job));
    // The table's devices are numbered first, so the runner can plan their lanes.
    let mut devices = Devices::planned(labels).map_err(|i| {
        format!(
            "--device-params: device {} is listed twice",
            labels.get(i).map_or("", String::as_str)
        )
    })?;
    let on_error = if job.keep_going {
        OnError::DropDevice
    } else {
        OnError::Stop
    };
    let mut any = false;
    let mut checks = InputChecks::new(job.units, job.strict);
    // The magnetometer is judged only where every file has one.
    let mut fleet_mag = true;
    // The file each device's first rows were in, by device number, for its warnings (the
    // devices of --device-params are numbered before any file is read).
    let mut first_file: Vec<Option<&Path>> = Vec::new();
    for (file, out) in files.iter().zip(outs) {
        let mut file_totals = Totals::default();
        let fleet = Fleet {
            runner: &mut runner,
            devices: &mut devices,
            checks: &mut checks,
            has_mag: &mut fleet_mag,
        };
        let result = run_fleet_file(
            job,
            fleet,
            on_error,
            &names,
            file,
            out,
            &mut file_totals,
            staged,
        );
        totals.failed_devices += file_totals.failed_devices;
        first_file.resize(devices.len(), None);
        for (d, seen) in first_file.iter_mut().enumerate() {
            if seen.is_none() && checks.rows(d as u32) > 0 {
                *seen = Some(file);
            }
        }
        match result {
            Ok(done) => {
                staged.push((file.clone(), done));
                any = true;
                totals.files += 1;
                totals.samples += file_totals.samples;
                totals.missing(file_totals.missing_imu);
            }
            Err(e) => totals.fail(e, job.keep_going)?,
        }
    }
    if !any {
        return Err("no input could be read".into());
    }
    totals.devices = (0..devices.len() as u32)
        .filter(|&d| checks.rows(d) > 0)
        .count();
    let seen = Seen {
        devices: &devices,
        first_file: &first_file,
    };
    judge_devices(job, &runner, &seen, &checks, fleet_mag, &mut totals)?;
    if let Some(table) = job.device_specs {
        let unseen: Vec<&str> = devices.unseen().collect();
        table.report(devices.len() - labels.len(), &unseen);
    }
    Ok(totals)
}

/// The run's fleet runner: every device with the run's spec, or the first `specs.len()`
/// devices with their own.
fn fleet_runner(job: &Job, specs: &[FilterSpec]) -> Result<FleetRunner, String> {
    FleetRunner::with_device_specs(job.spec, specs, job.precision, job.columns).map_err(|e| {
        format!(
            "--device-params: device {} runs another filter than the run's",
            e.channel
        )
    })
}

/// Warnings about devices beyond this many are summed up in one line.
const SHOWN_WARNINGS: usize = 5;

/// Judges every device of a fleet run once all files have run (see [`InputChecks::judge`]):
/// warnings printed (the first few), an all-skipped sensor an error (the run's, or under
/// `--keep-going` a failed device), rejections summed into `totals`.
fn judge_devices(
    job: &Job,
    runner: &FleetRunner,
    seen: &Seen<'_>,
    checks: &InputChecks,
    has_mag: bool,
    totals: &mut Totals,
) -> Result<(), String> {
    let mut warnings = 0usize;
    for d in 0..seen.devices.len() as u32 {
        let rejections = runner.rejections(d);
        totals.rejections += rejections;
        let what = match seen.first_file.get(d as usize) {
            Some(Some(file)) => format!("{}: device {}", file.display(), seen.devices.label(d)),
            _ => format!("device {}", seen.devices.label(d)),
        };
        let verdict = checks.judge(&what, d, rejections, job.nine_d && has_mag);
        for w in &verdict.warnings {
            if warnings < SHOWN_WARNINGS {
                eprintln!("warning: {w}");
            }
            warnings += 1;
        }
        if let Some(e) = verdict.error {
            if !job.keep_going {
                return Err(e);
            }
            eprintln!("error: {e}");
            totals.failed_devices += 1;
        }
    }
    if warnings > SHOWN_WARNINGS {
        eprintln!(
            "warning: {} more warning(s) like these about other devices",
            warnings - SHOWN_WARNINGS
        );
    }
    Ok(())
}

/// The devices of a fleet run and the file each was first seen in.
struct Seen<'a> {
    devices: &'a Devices,
    first_file: &'a [Option<&'a Path>],
}

/// The state of a fleet run that its files share.
struct Fleet<'a> {
    runner: &'a mut FleetRunner,
    devices: &'a mut Devices,
    checks: &'a mut InputChecks,
    /// Cleared by a file without magnetometer columns.
    has_mag: &'a mut bool,
}

#[allow(clippy::too_many_arguments)]
fn run_fleet_file(
    job: &Job,
    fleet: Fleet,
    on_error: OnError,
    names: &[&str],
    file: &Path,
    out: &Path,
    totals: &mut Totals,
    staged: &mut StagedFiles,
) -> Result<Staged, String> {
    let text = |e: ColumnarError| e.to_string();
    let Fleet {
        runner,
        devices,
        checks,
        has_mag,
    } = fleet;
    let mut reader = FleetReader::open(file, job.gaps)
        .map_err(text)?
        .with_units(job.units);
    check_mag(job, file, reader.has_mag())?;
    *has_mag &= reader.has_mag();
    let mut writer =
        EstimateWriter::create(out, job.format, reader.device_type(), names).map_err(text)?;
    let mut blocks = FleetBlocks::new();
    let mut any = false;
    loop {
        if interrupted() {
            drop(writer);
            staged.clear();
            exit_interrupted();
        }
        let Some((chunk, est)) = blocks
            .next_block(&mut reader, devices, runner, on_error, |chunk| {
                checks.observe(&chunk.block);
                job.calibrate(&mut chunk.block)
            })
            .map_err(text)?
        else {
            break;
        };
        any = true;
        for e in &est.failures {
            eprintln!(
                "error: {} (device {} left out from this row on)",
                FleetBlocks::locate(&reader, &chunk, devices, *e),
                devices.label(e.device())
            );
            totals.failed_devices += 1;
        }
        writer
            .write(&chunk, devices, &est, 0..chunk.block.len())
            .map_err(text)?;
        totals.samples += est.kept.iter().filter(|&&k| k).count() as u64;
        totals.missing_imu += chunk.missing_imu as u64;
    }
    if !any {
        return Err(ColumnarError::Empty {
            file: file.to_owned(),
        }
        .to_string());
    }
    if !reader.empty_parts().is_empty() {
        eprintln!(
            "note: {}: {} {} without rows skipped: {:?}",
            file.display(),
            reader.empty_parts().len(),
            if reader.format_name() == "Parquet" {
                "row group(s)"
            } else {
                "record batch(es)"
            },
            reader.empty_parts()
        );
    }
    writer.close().map_err(text)
}
