//! SIGINT and SIGTERM during `pathwave render`: a render in progress stops after its current pass and writes the
//! samples it has; at any other time the process ends at once, as it would without a handler.
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Set by the first signal while a render or a write is under way; the render loop checks it between passes.
pub static STOP: AtomicBool = AtomicBool::new(false);
/// How many `Busy` guards are alive: rendering, or writing the files (which must not be cut halfway).
static BUSY: AtomicUsize = AtomicUsize::new(0);

/// 128 + SIGINT, the shell's code for a process that a signal ended.
const INTERRUPTED_EXIT: i32 = 130;

pub fn install() -> anyhow::Result<()> {
    ctrlc::set_handler(|| {
        // Idle (loading, or --watch waiting for a change), or a second signal: nothing to save, end now.
        if BUSY.load(Ordering::SeqCst) == 0 || STOP.swap(true, Ordering::SeqCst) {
            eprintln!("\ninterrupted");
            std::process::exit(INTERRUPTED_EXIT);
        }
        eprintln!("\ninterrupted: finishing this pass and writing the samples done so far");
    })
    .map_err(|e| anyhow::anyhow!("cannot install the interrupt handler: {e}"))
}

/// Marks the process busy (a signal then stops the render instead of the process) while it lives.
pub struct Busy(());

impl Busy {
    pub fn begin() -> Self {
        BUSY.fetch_add(1, Ordering::SeqCst);
        Busy(())
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        BUSY.fetch_sub(1, Ordering::SeqCst);
    }
}
