//! host-sim's integration tests as one test binary: each file of this folder is a module
//! of it (one link and one copy of the crate's generic code instead of one per file;
//! `cargo test --test sim_tests -- FILE::` runs one file's tests).

mod common;

#[path = "bench_programs.rs"]
mod bench_programs;
#[path = "bring_up.rs"]
mod bring_up;
#[path = "circle_plots.rs"]
mod circle_plots;
#[path = "cli_inputs.rs"]
mod cli_inputs;
#[path = "compensation.rs"]
mod compensation;
#[path = "feedforward.rs"]
mod feedforward;
#[path = "figures_output.rs"]
mod figures_output;
#[path = "freqresp.rs"]
mod freqresp;
#[path = "freqresp_link.rs"]
mod freqresp_link;
#[path = "gantry_busy.rs"]
mod gantry_busy;
#[path = "gantry_inputs.rs"]
mod gantry_inputs;
#[path = "gantry_link.rs"]
mod gantry_link;
#[path = "gantry_operator.rs"]
mod gantry_operator;
#[path = "gantry_run_report.rs"]
mod gantry_run_report;
#[path = "gcode_compress.rs"]
mod gcode_compress;
#[path = "gcode_offsets.rs"]
mod gcode_offsets;
#[path = "gcode_overrides.rs"]
mod gcode_overrides;
#[path = "gcode_parse.rs"]
mod gcode_parse;
#[path = "gcode_programs.rs"]
mod gcode_programs;
#[path = "gcode_proptest.rs"]
mod gcode_proptest;
#[path = "gcode_sim.rs"]
mod gcode_sim;
#[path = "gcode_travel.rs"]
mod gcode_travel;
#[path = "machine_replay.rs"]
mod machine_replay;
#[path = "output_filters.rs"]
mod output_filters;
#[path = "program_run.rs"]
mod program_run;
#[path = "settings_atomic.rs"]
mod settings_atomic;
#[path = "sim_serve.rs"]
mod sim_serve;
#[path = "tune_link.rs"]
mod tune_link;
#[path = "twin_plant_cli.rs"]
mod twin_plant_cli;
#[path = "vibration.rs"]
mod vibration;
