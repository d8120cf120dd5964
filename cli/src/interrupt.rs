//! What a run says when it is interrupted (Ctrl-C, `kill`, a hang-up): where the results of its
//! finished cases are and how to go on. The signal handler writes the line made beforehand and ends
//! the process with the shell's status for the signal (128 + its number), as the signal itself would;
//! results are flushed per case, so what finished is on disk (a line cut by the signal is one a resume
//! repairs and a report names).

use std::sync::OnceLock;

static MESSAGE: OnceLock<Vec<u8>> = OnceLock::new();

extern "C" fn say_and_end(signal: libc::c_int) {
    if let Some(line) = MESSAGE.get() {
        // SAFETY: write(2) is async-signal-safe; the line was made before the handler was installed
        // and is never changed.
        unsafe { libc::write(2, line.as_ptr().cast(), line.len()) };
    }
    // SAFETY: _exit(2) is async-signal-safe and runs no handlers of the process.
    unsafe { libc::_exit(128 + signal) }
}

/// From now on SIGINT, SIGTERM and SIGHUP write `line` to standard error and end the process with
/// status 128 + the signal's number. Only the first call installs anything.
pub fn say_on_interrupt(line: String) {
    if MESSAGE.set(format!("\n{line}\n").into_bytes()).is_err() {
        return;
    }
    let handler: extern "C" fn(libc::c_int) = say_and_end;
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: the handler only does what is async-signal-safe (see `say_and_end`).
        unsafe { libc::signal(signal, handler as libc::sighandler_t) };
    }
}
