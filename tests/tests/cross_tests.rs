//! tests's integration tests as one test binary: each file of this folder is a module
//! of it (one link and one copy of the crate's generic code instead of one per file;
//! `cargo test --test cross_tests -- FILE::` runs one file's tests).

#[path = "encoder_noise.rs"]
mod encoder_noise;
#[path = "estimators_core.rs"]
mod estimators_core;
#[path = "estimators_helix.rs"]
mod estimators_helix;
#[path = "estimators_physical.rs"]
mod estimators_physical;
#[path = "faults.rs"]
mod faults;
#[path = "fixed_equivalence.rs"]
mod fixed_equivalence;
#[path = "fixed_powers.rs"]
mod fixed_powers;
#[path = "fixed_properties.rs"]
mod fixed_properties;
#[path = "flexible_frame.rs"]
mod flexible_frame;
#[path = "identify.rs"]
mod identify;
#[path = "machine_files.rs"]
mod machine_files;
#[path = "paper.rs"]
mod paper;
#[path = "properties.rs"]
mod properties;
#[path = "seeds_laws.rs"]
mod seeds_laws;
#[path = "settings_tree.rs"]
mod settings_tree;
