//! SIGINT and SIGTERM: a run or a simulation checks [`interrupted`] between blocks, drops
//! the files in progress (removing their temporary files) and exits with
//! [`EXIT_INTERRUPTED`], so a signal never leaves a temporary file behind and every final file
//! is complete.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by the SIGINT/SIGTERM handler. The run checks it between blocks: it drops the
/// estimate files in progress (removing their temporary files) and exits, so a signal never
/// leaves a temporary file behind and every final file is complete.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit code after SIGINT or SIGTERM (128 + SIGINT, as shells report an interrupt).
pub(crate) const EXIT_INTERRUPTED: i32 = 130;

/// On SIGINT or SIGTERM: set [`INTERRUPTED`]; the run stops at the end of the block it is
/// running (see [`interrupted`]).
pub(crate) fn install_signal_handler() -> Result<(), String> {
    ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst))
        .map_err(|e| format!("cannot install the signal handler: {e}"))
}

/// True once SIGINT or SIGTERM came: the caller drops its unfinished estimate files
/// (removing their temporary files) and calls [`exit_interrupted`].
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Ends the process after a signal, with [`EXIT_INTERRUPTED`]. Called with no estimate file
/// in progress or staged: a run puts its estimates in place only at its end, so none of
/// this run's is written (files from earlier runs keep their content).
pub fn exit_interrupted() -> ! {
    eprintln!(
        "interrupted: no estimate written (a run writes its estimates when all inputs have run)"
    );
    std::process::exit(EXIT_INTERRUPTED);
}
