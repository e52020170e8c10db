//! `gantry gui`: the operator's window on a machine (a board, the served simulated
//! gantry, QEMU, the board twin), over the same link and with the same session functions
//! as the `gantry` command line. The link runs on a thread of its own ([`session`]); the
//! window ([`app`], [`panels`]) draws what it tapped ([`live`]) and sends it commands.

pub mod app;
pub mod live;
pub mod panels;
pub mod script;
pub mod served;
pub mod session;
