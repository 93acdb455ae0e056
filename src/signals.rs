//! Ctrl-C and SIGTERM: one place that turns "stop" from the terminal (or a service
//! manager) into a callback, for the headless master and the window alike.
//!
//! A listener thread with a small tokio runtime waits for SIGINT or SIGTERM. Installing
//! handlers also matters when the process inherited SIGINT as *ignored* (a job started in
//! the background of a non-interactive shell): without a handler of our own such a demo
//! could not be stopped with Ctrl-C at all.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Which signal asked the process to stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopSignal {
    Interrupt,
    Terminate,
}

/// Calls `on_stop` (on the listener thread) at the first SIGINT or SIGTERM. Handlers are
/// installed before this returns.
pub fn on_stop_signal(on_stop: impl FnOnce(StopSignal) + Send + 'static) -> std::io::Result<()> {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let (mut int, mut term) = runtime.block_on(async { listeners() })?;
    std::thread::Builder::new().name("stop-signals".into()).spawn(move || {
        let signal = runtime.block_on(async {
            tokio::select! {
                _ = int.recv() => StopSignal::Interrupt,
                _ = term.recv() => StopSignal::Terminate,
            }
        });
        tracing::info!(?signal, "stop signal");
        on_stop(signal);
    })?;
    Ok(())
}

#[cfg(unix)]
type Listener = tokio::signal::unix::Signal;

#[cfg(unix)]
fn listeners() -> std::io::Result<(Listener, Listener)> {
    use tokio::signal::unix::{signal, SignalKind};
    Ok((signal(SignalKind::interrupt())?, signal(SignalKind::terminate())?))
}

/// A flag set at the first SIGINT or SIGTERM.
pub fn stop_flag() -> std::io::Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    let set = Arc::clone(&flag);
    on_stop_signal(move |_| set.store(true, Ordering::SeqCst))?;
    Ok(flag)
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn sigterm_reaches_the_callback() {
        let (tx, rx) = std::sync::mpsc::channel();
        on_stop_signal(move |s| tx.send(s).unwrap()).unwrap();
        // SAFETY: raising a signal this process handles.
        unsafe { libc::raise(libc::SIGTERM) };
        let got = rx.recv_timeout(Duration::from_secs(10)).expect("callback called");
        assert_eq!(got, StopSignal::Terminate);
    }
}
