//! A closed standard output (`gantry settings list | head`) ends the process quietly with
//! the shell's broken-pipe status (141) instead of a panic message: `println!` panics when
//! its write fails, and the reader having gone is not an error of the program.
//!
//! (The default SIGPIPE action would do the same for stdout, but also kill `gantry`
//! without a word when the QEMU rig's socket closes, where a lost link must be reported.)

/// Exit status of a process ended by SIGPIPE, as shells report it (128 + 13).
pub const BROKEN_PIPE_STATUS: i32 = 141;

/// Installs the panic hook: a failed print to stdout exits with [`BROKEN_PIPE_STATUS`];
/// every other panic goes to the default hook as before.
pub fn exit_quietly_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(BROKEN_PIPE_STATUS);
        }
        default(info);
    }));
}
