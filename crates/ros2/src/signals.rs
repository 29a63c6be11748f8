//! Stopping on SIGINT and SIGTERM: the signals set a flag that the node's loop reads, so it
//! saves and returns instead of being killed.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// A flag that becomes `true` on SIGINT or SIGTERM (a second signal of either kind after the
/// flag is set ends the process at once, as a stuck shutdown must stay stoppable).
///
/// # Errors
/// If the handlers cannot be installed.
pub fn stop_on_signals() -> std::io::Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // Registered first, so it runs before the flag is set: exit only on a second signal.
        signal_hook::flag::register_conditional_shutdown(signal, 130, Arc::clone(&stop))?;
        signal_hook::flag::register(signal, Arc::clone(&stop))?;
    }
    Ok(stop)
}
