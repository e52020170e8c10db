//! The scenario to run, from the semihosting command line (`SYS_GET_CMDLINE`). QEMU
//! passes `-semihosting-config enable=on,target=native,arg=firmware,arg=NAME` as the
//! words `firmware NAME`: the first word is the program name, the second the scenario.

/// Longest command line read, bytes.
const CMDLINE_BYTES: usize = 256;

/// Scenario run when the command line names none (`cargo fw-qemu` names it anyway).
pub const DEFAULT_SCENARIO: &str = "paper_helix_dsmc";

/// Calls `f` with the scenario name on the command line (or [`DEFAULT_SCENARIO`]); the
/// name lives in a stack buffer only for the call.
pub fn with_scenario_name<T>(f: impl FnOnce(&str) -> T) -> T {
    let args = match semihosting::experimental::env::args::<CMDLINE_BYTES>() {
        Ok(a) => a,
        Err(_) => {
            defmt::warn!(
                "no semihosting command line; running {=str}",
                DEFAULT_SCENARIO
            );
            return f(DEFAULT_SCENARIO);
        }
    };
    let mut words = &args;
    // the program name, then the scenario
    let _program = words.next();
    match words.next() {
        Some(Ok(name)) => f(name),
        Some(Err(_)) => f("<not UTF-8>"),
        None => f(DEFAULT_SCENARIO),
    }
}
