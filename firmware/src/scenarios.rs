//! The QEMU rig's scenarios: host-sim's files `host-sim/scenarios/qemu/*.toml`, resolved
//! at build time by gantry-scenario into the core's [`RunConfig`] and carried as postcard
//! bytes (firmware/build.rs). The rig decodes the one it is told to run at boot.

use controller_core::sim::run::RunConfig;

include!(concat!(env!("OUT_DIR"), "/qemu_scenarios.rs"));

/// Why a scenario cannot run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScenarioError {
    /// No scenario of that name in the table.
    Unknown,
    /// The table's bytes do not decode (a firmware/table mismatch: rebuild).
    Decode,
}

/// The postcard bytes of scenario `name`.
pub fn find(name: &str) -> Option<&'static [u8]> {
    SCENARIOS.iter().find(|(n, _)| *n == name).map(|(_, b)| *b)
}

/// The run configuration of scenario `name`.
pub fn load(name: &str) -> Result<RunConfig, ScenarioError> {
    let bytes = find(name).ok_or(ScenarioError::Unknown)?;
    postcard::from_bytes(bytes).map_err(|_| ScenarioError::Decode)
}

/// Every scenario name, in table (alphabetical) order.
pub fn names() -> impl Iterator<Item = &'static str> {
    SCENARIOS.iter().map(|(n, _)| *n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::machine::scope::Scope;
    use controller_core::machine::{MachineMemory, MachinePlanner};
    use controller_core::sim::run::{factory_planner, SimRun};
    use std::path::PathBuf;

    fn dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/qemu")
    }

    #[test]
    fn every_file_is_in_the_table_and_decodes_to_what_gantry_scenario_resolves() {
        let mut files: Vec<_> = std::fs::read_dir(dir())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        assert!(files.len() >= 4, "{files:?}");
        assert_eq!(files.len(), SCENARIOS.len());
        for path in files {
            let name = path.file_stem().unwrap().to_str().unwrap();
            let file = gantry_scenario::load(&path).unwrap();
            let resolved = gantry_scenario::Resolved::new(&file.file, &file.runs[0]).unwrap();
            let decoded = load(name).unwrap();
            assert_eq!(decoded, resolved.run, "{name}");
            // and it runs: a few hundred periods in f32 stay finite and enabled (a program
            // run's machine has a planner, as in the rig)
            let memory = Box::new(MachineMemory {
                planner: MachinePlanner::BLANK,
                scope: Scope::new(),
                comp: controller_core::motion::compensation::CompTables::NONE,
                comp_entry: controller_core::machine::CompEntry::NONE,
                response: controller_core::machine::ResponseRecord::EMPTY,
                shaper: controller_core::motion::shaper::ShaperStage::NONE,
                queue: controller_core::machine::RequestQueue::new(),
                next_settings: None,
                settings: controller_core::settings::FACTORY,
            });
            let planner = factory_planner(decoded.servo.rate_hz);
            let mut run = SimRun::<f32, _, _>::with_memory(&decoded, &planner, memory).unwrap();
            for _ in 0..300 {
                run.control();
                run.finish_period();
            }
            let s = run.servo().snapshot();
            assert!(s.outputs_on, "{name}: {:?}", s.state);
            assert!(s.effort.iter().all(|u| u.is_finite()), "{name}");
            assert_eq!(run.figures().samples, 300, "{name}");
        }
    }

    #[test]
    fn unknown_names_and_corrupt_bytes_are_refused() {
        assert_eq!(load("no_such_scenario"), Err(ScenarioError::Unknown));
        assert!(names().any(|n| n == "paper_helix_dsmc"));
        let bytes = find("paper_helix_dsmc").unwrap();
        assert!(postcard::from_bytes::<RunConfig>(&bytes[..bytes.len() / 2]).is_err());
    }
}
