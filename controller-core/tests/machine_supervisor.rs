//! The machine's supervisor (`machine::Machine`) on the simulated gantry: requests in
//! order, refusals with their reasons, a program through the planner, a bad segment
//! stopping the program, settings only with the outputs off, link loss.

use controller_core::machine::messages::{Outcome, Request};
use controller_core::machine::{
    Channels, Down, LinkSide, LinkState, Machine, MachineMemory, MachinePlanner, MachinePort,
};

type M = Machine<Box<MachineMemory>>;
use controller_core::motion::planner::Segment;
use controller_core::presets::gantry::GANTRY_AXES;
use controller_core::servo::ServoState;
use controller_core::settings::{Settings, FACTORY, PLACEHOLDER_MODELS};
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, PlantConfig, SwitchConfig, World, WorldConfig,
};

const RATE_HZ: u32 = 10_000;

/// The designed gantry with its models entered and homing off (the axes start referenced).
fn settings() -> Settings {
    let mut s = FACTORY;
    for (a, m) in s.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
        a.homing.enabled = false;
    }
    s
}

/// The simulated gantry for the servo configuration of `s`.
fn world(s: &Settings) -> World {
    let wcfg = WorldConfig {
        plants: GANTRY_AXES.map(PlantConfig::Physical),
        plant_substeps: 4,
        initial: [InitialState::default(); 3],
        switches: [SwitchConfig::NONE; 3],
        imperfections: ImperfectionConfig::default(),
        brakes: Default::default(),
    };
    World::new(&wcfg, &s.servo_config(RATE_HZ).unwrap()).unwrap()
}

fn machine() -> (M, World) {
    let s = settings();
    let world = world(&s);
    let m = Machine::new(
        &s,
        RATE_HZ,
        world.counter_registers(),
        world.counts(),
        Box::new(MachineMemory::BLANK),
    )
    .unwrap();
    (m, world)
}

fn periods(m: &mut M, w: &mut World, n: u32) {
    for _ in 0..n {
        m.period(w);
        w.advance();
    }
}

#[test]
fn a_program_runs_to_its_end_and_the_machine_returns_to_idle() {
    let (mut m, mut w) = machine();
    m.submit(Request::Arm);
    m.submit(Request::Run);
    for k in 1..=20u32 {
        let x = if k % 2 == 1 { 10.0 } else { 0.0 };
        m.submit(Request::Segment(Segment::line([x, 0.0, 0.0], 50.0, k)));
        periods(&mut m, &mut w, 2);
    }
    m.submit(Request::EndProgram);
    let mut k = 0;
    while !(m.status().program_done && m.servo().state() == ServoState::Idle) {
        periods(&mut m, &mut w, 100);
        k += 100;
        assert!(k < 200_000, "the program did not end");
    }
    let s = m.status();
    assert_eq!(s.executed, 23);
    assert_eq!(s.last, Outcome::Done);
    // it ends where the last segment ends, on the path
    assert!(s.pos_mm[0].abs() < 0.01, "{:?}", s.pos_mm);
    assert!(!m.servo().faults().any());
}

#[test]
fn a_bad_segment_is_refused_and_stops_the_program() {
    let (mut m, mut w) = machine();
    m.submit(Request::Arm);
    m.submit(Request::Run);
    periods(&mut m, &mut w, 3);
    m.submit(Request::Segment(Segment::line(
        [5.0, 0.0, 0.0],
        f32::NAN,
        1,
    )));
    // (the stop settles before Idle)
    periods(&mut m, &mut w, 1000);
    let s = m.status();
    let Outcome::Refused(why) = &s.last else {
        panic!("{:?}", s.last)
    };
    assert!(why.contains("program stopped"), "{why}");
    assert_eq!(m.servo().state(), ServoState::Idle);
    m.submit(Request::Segment(Segment::line([5.0, 0.0, 0.0], 10.0, 2)));
    periods(&mut m, &mut w, 1);
    assert!(matches!(m.status().last, Outcome::Refused(_)));
}

/// `requests` through the link's queues (as the firmware's link task hands them down),
/// one period after each; the outcome of the last.
fn through_link(
    m: &mut M,
    w: &mut World,
    ch: &mut Channels,
    st: &mut LinkState,
    requests: Vec<Request>,
) -> Outcome {
    for r in requests {
        let (ends, mut ctl) = ch.split();
        let mut link = LinkSide::new(ends, st);
        link.down(Down::Request(r));
        m.linked_period(w, &mut ctl);
        w.advance();
        // settings requests wait for the ones before them: a few periods
        for _ in 0..3 {
            let (ends, mut ctl) = ch.split();
            LinkSide::new(ends, st).poll();
            m.linked_period(w, &mut ctl);
            w.advance();
        }
    }
    m.status().last
}

#[test]
fn settings_change_only_with_the_outputs_off_and_a_refusal_says_why() {
    let (mut m, mut w) = machine();
    let mut ch = Channels::new();
    let mut st = LinkState::new(m.settings(), RATE_HZ);
    let set = |k: &str, v: &str| Request::SettingSet {
        key: k.try_into().unwrap(),
        value: v.try_into().unwrap(),
    };
    let get = |k: &str| Request::SettingGet {
        key: k.try_into().unwrap(),
    };
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![set("axis.x.law.bandwidth_rad_s", "300")],
    );
    assert_eq!(o, Outcome::Done);
    assert_eq!(m.settings().axis[0].law.bandwidth_rad_s, 300.0);
    // the link side's copy follows the machine's
    assert_eq!(st.settings().axis[0].law.bandwidth_rad_s, 300.0);
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![get("axis.x.law.bandwidth_rad_s")],
    );
    assert_eq!(o, Outcome::Value("300".try_into().unwrap()));
    // out of range: refused naming the key, nothing changes
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![set("axis.x.law.bandwidth_rad_s", "-5")],
    );
    let Outcome::Refused(why) = o else {
        panic!("{o:?}")
    };
    assert!(why.contains("axis.x.law.bandwidth_rad_s"), "{why}");
    assert_eq!(m.settings().axis[0].law.bandwidth_rad_s, 300.0);
    // arm and a set, pipelined: the set is resolved once the arm was executed, and the
    // gain change is refused with the outputs on
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![Request::Arm, set("axis.x.law.bandwidth_rad_s", "400")],
    );
    let Outcome::Refused(why) = o else {
        panic!("{o:?}")
    };
    assert!(why.contains("outputs off"), "{why}");
    assert_eq!(m.settings().axis[0].law.bandwidth_rad_s, 300.0);
    assert_eq!(st.settings().axis[0].law.bandwidth_rad_s, 300.0);
    // every request counted, in order
    assert_eq!(m.status().executed, 5);
    assert_eq!(m.retired(), 5);
    m.submit(Request::Jog {
        axis: 7,
        vel_mm_s: 1.0,
    });
    periods(&mut m, &mut w, 1);
    assert!(matches!(m.status().last, Outcome::Refused(_)));
}

#[test]
fn work_offsets_and_tools_change_while_a_program_runs() {
    let (mut m, mut w) = machine();
    let mut ch = Channels::new();
    let mut st = LinkState::new(m.settings(), RATE_HZ);
    let set = |k: &str, v: &str| Request::SettingSet {
        key: k.try_into().unwrap(),
        value: v.try_into().unwrap(),
    };
    // a 40 mm move at 20 mm/s: 2 s, still moving when the settings arrive
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![
            Request::Arm,
            Request::Run,
            Request::Segment(Segment::line([40.0, 0.0, 0.0], 20.0, 1)),
        ],
    );
    assert_eq!(o, Outcome::Done);
    periods(&mut m, &mut w, 2_000);
    assert_eq!(m.servo().state(), ServoState::Run);
    let moving_at = m.status().pos_mm[0];
    assert!(moving_at > 1.0 && moving_at < 39.0, "{moving_at}");
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![set("work.g55.x_mm", "125.5"), set("tool.2.length_mm", "42")],
    );
    assert_eq!(o, Outcome::Done);
    assert_eq!(m.settings().work.g55.x_mm, 125.5);
    assert_eq!(m.settings().tool.t2.length_mm, 42.0);
    assert_eq!(st.settings().work.g55.x_mm, 125.5);
    // the program goes on
    assert_eq!(m.servo().state(), ServoState::Run);
    assert!(!m.servo().faults().any());
    // a servo parameter in the same state is still refused
    let o = through_link(
        &mut m,
        &mut w,
        &mut ch,
        &mut st,
        vec![set("axis.x.law.bandwidth_rad_s", "300")],
    );
    assert!(matches!(o, Outcome::Refused(_)), "{o:?}");
}

#[test]
fn link_loss_stops_a_running_program_with_a_link_lost_fault() {
    let (mut m, mut w) = machine();
    m.submit(Request::Arm);
    m.submit(Request::Run);
    m.submit(Request::Segment(Segment::line([100.0, 0.0, 0.0], 100.0, 1)));
    periods(&mut m, &mut w, 3000);
    assert!(m.status().vel_mm_s[0] > 50.0);
    m.link_lost();
    periods(&mut m, &mut w, 3000);
    assert_eq!(
        m.servo().faults().first().unwrap().fault.kind.name(),
        "link_lost"
    );
    assert!(m.status().vel_mm_s[0].abs() < 1.0);
    assert_eq!(m.servo().state(), ServoState::Fault);
}

/// The program of the first test, on the link's path: requests through the queues of
/// `machine::port` (as the firmware's link task hands them to the control interrupt),
/// the credit never lets more requests in flight than the machine's queue holds, status
/// replies come back up with their ids, telemetry at the subscribed rate.
#[test]
fn requests_through_the_link_queues_respect_the_credit_and_get_replies() {
    use controller_core::link::{RealtimeRequest, Seq};
    use controller_core::machine::{Up, REQUEST_QUEUE};
    let (mut m, mut w) = machine();
    let mut ch = Channels::new();
    let mut st = LinkState::new(m.settings(), RATE_HZ);
    let mut program = vec![
        Request::Subscribe {
            every_periods: 100,
            signals: heapless::Vec::new(),
        },
        Request::Arm,
        Request::Run,
    ];
    for k in 1..=40u32 {
        let x = if k % 2 == 1 { 10.0 } else { 0.0 };
        program.push(Request::Segment(Segment::line([x, 0.0, 0.0], 50.0, k)));
    }
    program.push(Request::EndProgram);
    let total = program.len() as u32;
    let mut next = program.into_iter();
    let mut pending = next.next();
    let (mut statuses, mut telemetry, mut max_queued) = (0u32, 0u32, 0usize);
    let mut periods_run = 0u32;
    loop {
        let (ends, mut ctl) = ch.split();
        let mut link = LinkSide::new(ends, &mut st);
        // the host sends while the credit allows
        while let Some(r) = pending.take() {
            if link.free_slots() == 0 {
                pending = Some(r);
                break;
            }
            link.down(Down::Request(r));
            pending = next.next();
        }
        if periods_run.is_multiple_of(1000) {
            link.down(Down::Realtime {
                id: Seq(periods_run as u16),
                req: RealtimeRequest::Status,
            });
        }
        m.linked_period(&mut w, &mut ctl);
        w.advance();
        periods_run += 1;
        max_queued = max_queued.max(m.status().queued as usize);
        while let Some(u) = link.up() {
            match u {
                Up::Status { id, status } => {
                    assert_eq!(id.0, (periods_run - 1) as u16);
                    assert!(status.period >= periods_run - 1);
                    statuses += 1;
                }
                Up::Telemetry(t) => {
                    assert_eq!(t.period % 100, 0, "{}", t.period);
                    telemetry += 1;
                }
            }
        }
        if pending.is_none() && m.status().program_done && periods_run > 10 {
            break;
        }
        assert!(periods_run < 300_000, "the program did not end");
    }
    assert!(max_queued <= REQUEST_QUEUE);
    assert_eq!(m.retired(), total);
    assert_eq!(m.status().executed, total);
    assert_eq!(statuses, periods_run.div_ceil(1000));
    // one sample per 100 periods from the subscription on (±1 for the ends)
    assert!(
        telemetry.abs_diff(periods_run / 100) <= 1,
        "{telemetry} in {periods_run}"
    );
    assert!(m.status().pos_mm[0].abs() < 0.01);
}

/// A planner restarted in place is the planner `new` builds, and runs a program the same
/// to the bit.
#[test]
fn a_planner_restarted_in_place_equals_a_new_one() {
    let cfg = settings().planner_config(RATE_HZ);
    let mut used = Box::new(MachinePlanner::new(&cfg, [0.0; 3]).unwrap());
    for k in 1..=10u32 {
        used.push(&Segment::line([k as f32, (k % 3) as f32, 0.0], 80.0, k))
            .unwrap();
    }
    for _ in 0..1500 {
        used.tick();
    }
    used.hold();
    for _ in 0..50 {
        used.tick();
    }
    let start = [3.0, -2.0, 1.0];
    used.restart(&cfg, start).unwrap();
    let mut fresh = Box::new(MachinePlanner::new(&cfg, start).unwrap());
    assert_eq!(used.planner(), fresh.planner());
    // and so is the blank one, restarted
    let mut blank = Box::new(MachinePlanner::BLANK);
    blank.restart(&cfg, start).unwrap();
    assert_eq!(blank.planner(), fresh.planner());
    for k in 1..=6u32 {
        let seg = Segment::line([3.0 + k as f32, -2.0, 1.0 + (k % 2) as f32], 60.0, k);
        used.push(&seg).unwrap();
        fresh.push(&seg).unwrap();
    }
    for _ in 0..8000 {
        assert_eq!(used.tick(), fresh.tick());
    }
    // a bad configuration changes nothing
    let mut bad = cfg;
    bad.period_s = -1.0;
    assert!(used.restart(&bad, [0.0; 3]).is_err());
    assert_eq!(used.planner(), fresh.planner());
}

/// Settings saves through the link (`machine::save`): written only with the outputs off,
/// nothing arms while the flash is written, a new session cancels a save on both sides.
#[cfg(feature = "store")]
mod save {
    use super::*;
    use controller_core::machine::save_due_into;
    use controller_core::servo::Command;
    use controller_core::settings::store::{
        block_on, BlockingFlash, LoadOutcome, RamFlash, SettingsStore,
    };

    type Store = SettingsStore<BlockingFlash<RamFlash<8192, 4096>>>;

    fn store() -> Store {
        SettingsStore::new(
            BlockingFlash::new(RamFlash::new(), 0, 8192).unwrap(),
            0..8192,
        )
        .unwrap()
    }

    /// One period behind the link, the link side writing a save that is due.
    fn linked(m: &mut M, w: &mut World, ch: &mut Channels, st: &mut LinkState, s: &mut Store) {
        let (ends, mut ctl) = ch.split();
        let mut link = LinkSide::new(ends, st);
        link.poll();
        save_due_into(&mut link, s);
        m.linked_period(w, &mut ctl);
        w.advance();
    }

    fn send(ch: &mut Channels, st: &mut LinkState, r: Request) {
        let (ends, _) = ch.split();
        LinkSide::new(ends, st).down(Down::Request(r));
    }

    /// A save sent and periods run without the link side writing: the machine holds the
    /// lock.
    fn lock_for_save(m: &mut M, w: &mut World, ch: &mut Channels, st: &mut LinkState) {
        send(ch, st, Request::SettingsSave);
        for _ in 0..3 {
            let (ends, mut ctl) = ch.split();
            LinkSide::new(ends, st).poll();
            m.linked_period(w, &mut ctl);
            w.advance();
        }
        assert!(m.saving());
    }

    #[test]
    fn a_save_stores_the_settings_the_machine_runs_for_the_next_boot() {
        let (mut m, mut w) = machine();
        let (mut ch, mut s) = (Channels::new(), store());
        let mut st = LinkState::new(m.settings(), RATE_HZ);
        send(
            &mut ch,
            &mut st,
            Request::SettingSet {
                key: "axis.x.law.bandwidth_rad_s".try_into().unwrap(),
                value: "300".try_into().unwrap(),
            },
        );
        send(&mut ch, &mut st, Request::SettingsSave);
        for _ in 0..10 {
            linked(&mut m, &mut w, &mut ch, &mut st, &mut s);
        }
        assert_eq!(m.status().last, Outcome::Done);
        assert_eq!(m.status().executed, 2);
        assert_eq!(m.retired(), 2);
        assert!(!m.saving());
        let (loaded, how) = block_on(s.load(RATE_HZ));
        assert_eq!(how, LoadOutcome::Stored);
        assert_eq!(loaded.axis[0].law.bandwidth_rad_s, 300.0);
        assert_eq!(loaded, *m.settings());
    }

    #[test]
    fn a_save_with_the_outputs_on_is_refused_and_writes_nothing() {
        let (mut m, mut w) = machine();
        let (mut ch, mut s) = (Channels::new(), store());
        let mut st = LinkState::new(m.settings(), RATE_HZ);
        send(&mut ch, &mut st, Request::Arm);
        send(&mut ch, &mut st, Request::SettingsSave);
        for _ in 0..10 {
            linked(&mut m, &mut w, &mut ch, &mut st, &mut s);
        }
        assert!(m.servo().state().drives());
        let Outcome::Refused(why) = m.status().last else {
            panic!("{:?}", m.status().last)
        };
        assert!(why.contains("disarm first"), "{why}");
        assert_eq!(m.status().executed, 2);
        assert_eq!(block_on(s.load(RATE_HZ)).1, LoadOutcome::Empty);
        // the link side is not stuck: the next request goes through
        send(&mut ch, &mut st, Request::Disarm);
        // the outputs go off once the Z brake grips (engage_s = 300 periods)
        for _ in 0..310 {
            linked(&mut m, &mut w, &mut ch, &mut st, &mut s);
        }
        assert_eq!(m.status().executed, 3);
        assert!(!m.servo().state().drives());
    }

    #[test]
    fn nothing_arms_while_the_flash_is_written() {
        let (mut m, mut w) = machine();
        let (mut ch, mut s) = (Channels::new(), store());
        let mut st = LinkState::new(m.settings(), RATE_HZ);
        lock_for_save(&mut m, &mut w, &mut ch, &mut st);
        // the arm button and an arm request behind the save both wait
        m.local(Command::Arm);
        send(&mut ch, &mut st, Request::Arm);
        for _ in 0..20 {
            let (ends, mut ctl) = ch.split();
            let mut link = LinkSide::new(ends, &mut st);
            link.poll();
            assert!(link.save_due().is_some());
            m.linked_period(&mut w, &mut ctl);
            w.advance();
            assert_eq!(m.servo().state(), ServoState::Disabled);
        }
        assert_eq!(m.status().executed, 0);
        // written: the lock goes, then the button's arm and the queued arm run
        for _ in 0..10 {
            linked(&mut m, &mut w, &mut ch, &mut st, &mut s);
        }
        assert!(!m.saving());
        assert!(m.servo().state().drives());
        assert_eq!(m.status().executed, 2);
        assert_eq!(block_on(s.load(RATE_HZ)).1, LoadOutcome::Stored);
    }

    #[test]
    fn a_new_session_cancels_a_save_on_both_sides() {
        let (mut m, mut w) = machine();
        let (mut ch, mut s) = (Channels::new(), store());
        let mut st = LinkState::new(m.settings(), RATE_HZ);
        lock_for_save(&mut m, &mut w, &mut ch, &mut st);
        {
            let (ends, mut ctl) = ch.split();
            let mut link = LinkSide::new(ends, &mut st);
            link.down(Down::SessionStarted);
            assert!(link.save_due().is_none());
            m.linked_period(&mut w, &mut ctl);
            w.advance();
        }
        assert!(!m.saving());
        // nothing is written afterwards, and the new session's requests run
        send(&mut ch, &mut st, Request::Arm);
        for _ in 0..10 {
            linked(&mut m, &mut w, &mut ch, &mut st, &mut s);
        }
        assert_eq!(block_on(s.load(RATE_HZ)).1, LoadOutcome::Empty);
        assert!(m.servo().state().drives());
        assert_eq!(m.status().executed, 1);
    }
}

/// The planner across two tasks (`motion::planner::split`), as the board runs it: the
/// machine's period samples, the planning task (here: called after the period, or not
/// at all for a while) plans.
mod split {
    use super::*;
    use controller_core::machine::scope::Scope;
    use controller_core::motion::planner::{
        Planner, PlannerChannels, PlannerHandle, SplitExecutor, SplitPlanner,
    };

    type Exec = SplitExecutor<'static>;
    type SplitMachine = Machine<Box<MachineMemory<Exec>>, Exec>;
    type Task = SplitPlanner<'static, 32, 128>;

    /// (channels and planner leaked: a test's machine lives as long as the test)
    fn ends() -> (Exec, Task) {
        let ch: &'static mut PlannerChannels = Box::leak(Box::new(PlannerChannels::new()));
        let (ex, pl) = ch.split();
        let planner: &'static mut Planner<32, 128> = Box::leak(Box::new(Planner::BLANK));
        let mut exec = SplitExecutor::DETACHED;
        exec.attach(ex);
        (exec, SplitPlanner::new(planner, pl))
    }

    fn split_machine() -> (SplitMachine, Task, World) {
        let (_, w) = machine();
        let (exec, task) = ends();
        let m = Machine::new(
            &settings(),
            RATE_HZ,
            w.counter_registers(),
            w.counts(),
            Box::new(MachineMemory {
                planner: exec,
                scope: Scope::new(),
                comp: controller_core::motion::compensation::CompTables::NONE,
                comp_entry: controller_core::machine::CompEntry::NONE,
                response: controller_core::machine::ResponseRecord::EMPTY,
                shaper: controller_core::motion::shaper::ShaperStage::NONE,
                queue: controller_core::machine::RequestQueue::new(),
                next_settings: None,
                settings: controller_core::settings::FACTORY,
            }),
        )
        .unwrap();
        (m, task, w)
    }

    /// A zig-zag with arcs between, `n` segments.
    fn program(n: u32) -> Vec<Request> {
        let mut r = vec![Request::Arm, Request::Run];
        for k in 1..=n {
            let x = if k % 2 == 1 { 8.0 } else { 0.0 };
            r.push(Request::Segment(Segment::line(
                [x, k as f32 * 0.5, 0.0],
                60.0,
                k,
            )));
        }
        r.push(Request::EndProgram);
        r
    }

    /// Periods until the program is done; the largest reference step per period (mm).
    fn run_split(
        m: &mut SplitMachine,
        t: &mut Task,
        w: &mut World,
        reqs: &[Request],
        starve: std::ops::Range<u32>,
    ) -> (u32, f32) {
        let mut reqs = reqs.iter();
        let mut last = m.servo().snapshot().reference;
        let mut max_step = 0.0f32;
        for p in 0..400_000u32 {
            feed(m.free_slots(), &mut reqs, |r| m.submit(r));
            m.period(w);
            w.advance();
            if !starve.contains(&p) {
                t.run();
            }
            let r = m.servo().snapshot().reference;
            let d = (0..3).map(|i| (r[i] - last[i]).abs()).fold(0.0, f32::max);
            max_step = max_step.max(d);
            last = r;
            if p > 10 && m.status().program_done && m.servo().state() == ServoState::Idle {
                return (p, max_step);
            }
        }
        panic!("the program did not end");
    }

    /// Requests within the machine's credit, as the link sends them.
    fn feed<'a>(
        free: u16,
        reqs: &mut impl Iterator<Item = &'a Request>,
        mut submit: impl FnMut(Request),
    ) {
        for _ in 0..free {
            match reqs.next() {
                Some(r) => submit(r.clone()),
                None => return,
            }
        }
    }

    fn run_single(m: &mut M, w: &mut World, reqs: &[Request]) -> u32 {
        let mut reqs = reqs.iter();
        for p in 0..400_000u32 {
            feed(m.free_slots(), &mut reqs, |r| m.submit(r));
            m.period(w);
            w.advance();
            if p > 10 && m.status().program_done && m.servo().state() == ServoState::Idle {
                return p;
            }
        }
        panic!("the program did not end");
    }

    #[test]
    fn the_program_runs_as_with_both_halves_in_the_period() {
        let reqs = program(24);
        let (mut a, mut wa) = machine();
        let single = run_single(&mut a, &mut wa, &reqs);
        let (mut b, mut task, mut wb) = split_machine();
        let (split, max_step) = run_split(&mut b, &mut task, &mut wb, &reqs, 0..0);
        let (sa, sb) = (a.status(), b.status());
        assert_eq!(sa.executed, sb.executed);
        assert_eq!(sb.last, Outcome::Done);
        for i in 0..3 {
            assert!((sa.pos_mm[i] - sb.pos_mm[i]).abs() < 1e-3, "{sa:?} {sb:?}");
        }
        assert!((sb.pos_mm[1] - 12.0).abs() < 0.01, "{:?}", sb.pos_mm);
        eprintln!("24 segments: split {split} periods, single thread {single} periods");
        // a segment's result comes back a period later; the motion is the same
        let diff = split.abs_diff(single);
        assert!(diff <= 10, "split {split} periods, single {single}");
        // no jump: at most the 60 mm/s feed (x override 2) per period
        assert!(max_step < 120.0 / RATE_HZ as f32, "{max_step}");
        assert!(!b.servo().faults().any());
    }

    #[test]
    fn a_starved_planning_task_stops_on_the_path_and_the_program_completes() {
        let reqs = program(12);
        let (mut m, mut task, mut w) = split_machine();
        // the task misses 300 periods (30 ms) in the middle of the program, at speed
        let (_, max_step) = run_split(&mut m, &mut task, &mut w, &reqs, 3_000..3_300);
        let s = m.status();
        assert_eq!(s.last, Outcome::Done);
        assert!((s.pos_mm[1] - 6.0).abs() < 0.01, "{:?}", s.pos_mm);
        assert!(max_step < 120.0 / RATE_HZ as f32, "{max_step}");
        assert!(!m.servo().faults().any());
    }

    #[test]
    fn the_task_stopping_leaves_the_executor_at_rest_on_the_path() {
        let (mut m, mut task, mut w) = split_machine();
        m.submit(Request::Arm);
        m.submit(Request::Run);
        m.submit(Request::Segment(Segment::line([50.0, 0.0, 0.0], 100.0, 1)));
        for _ in 0..3_000 {
            m.period(&mut w);
            w.advance();
            task.run();
        }
        let v0 = m.status().vel_mm_s[0];
        assert!(v0 > 90.0, "{v0}");
        // the task never runs again: the steps run out, the executor brakes by itself
        let mut last_vel = v0;
        let mut max_dv = 0.0f32;
        for _ in 0..3_000 {
            m.period(&mut w);
            w.advance();
            let v = m.servo().snapshot().reference[0];
            let _ = v;
            let vel = m.status().vel_mm_s[0];
            max_dv = max_dv.max((vel - last_vel).abs());
            last_vel = vel;
        }
        assert!(
            m.status().vel_mm_s[0].abs() < 0.5,
            "{:?}",
            m.status().vel_mm_s
        );
        let x = m.status().pos_mm[0];
        assert!(x > 20.0 && x < 50.0, "{x}");
        // braking within the axis' acceleration limit (2000 mm/s²) and the servo's lag
        assert!(max_dv < 2.0, "{max_dv}");
        assert!(!m.servo().faults().any());
    }

    #[test]
    fn a_bad_segment_is_refused_in_request_order() {
        let (mut m, mut task, mut w) = split_machine();
        m.submit(Request::Arm);
        m.submit(Request::Run);
        m.submit(Request::Segment(Segment::line([5.0, 0.0, 0.0], 20.0, 1)));
        m.submit(Request::Segment(Segment::line([6.0, 0.0, 0.0], -1.0, 2)));
        m.submit(Request::Segment(Segment::line([7.0, 0.0, 0.0], 20.0, 3)));
        let mut outcomes = Vec::new();
        let mut executed = 0;
        // (the program starts once the Z brake is open, 700 periods after arming)
        for _ in 0..720 {
            m.period(&mut w);
            w.advance();
            task.run();
            let s = m.status();
            if s.executed != executed {
                executed = s.executed;
                outcomes.push(s.last.clone());
            }
        }
        // arm, run, the good segment, then the bad one refused; the third is flushed
        assert_eq!(executed, 4, "{outcomes:?}");
        let Outcome::Refused(why) = outcomes.last().unwrap() else {
            panic!("{outcomes:?}")
        };
        assert!(why.contains("feed must be > 0"), "{why}");
        assert_eq!(m.status().queued, 0);
    }

    #[test]
    fn a_restart_drops_what_the_last_run_left_in_the_queues() {
        let (mut exec, mut task) = ends();
        let cfg = settings().planner_config(RATE_HZ);
        exec.restart(&cfg, [0.0; 3]).unwrap();
        task.run();
        for k in 1..=8u32 {
            let seg = Segment::line([k as f32 * 2.0, 0.0, 0.0], 80.0, k);
            while exec.offer(&seg) != controller_core::motion::planner::Offer::Taken {
                exec.tick();
                task.run();
            }
        }
        for _ in 0..500 {
            exec.tick();
            task.run();
        }
        let p = exec.tick().pos_mm.to_array();
        assert!(p[0] > 0.3, "{p:?} {:?}", exec.report());
        // spans and steps of the first run are in the queues; a new run starts elsewhere
        let start = [-4.0, 3.0, 1.0];
        exec.restart(&cfg, start).unwrap();
        for _ in 0..5 {
            assert_eq!(exec.tick().pos_mm.to_array(), start);
        }
        task.run();
        let seg = Segment::line([-4.0, 8.0, 1.0], 50.0, 1);
        let mut last = start;
        let mut n = 0;
        loop {
            match exec.offer(&seg) {
                controller_core::motion::planner::Offer::Taken => break,
                controller_core::motion::planner::Offer::Refused(e) => panic!("{e:?}"),
                controller_core::motion::planner::Offer::Later => {}
            }
            let p = exec.tick().pos_mm.to_array();
            assert_eq!(p, start);
            task.run();
            n += 1;
            assert!(n < 5);
        }
        for _ in 0..20_000 {
            let p = exec.tick().pos_mm.to_array();
            task.run();
            assert_eq!(p[0], -4.0);
            assert!(
                (p[1] - last[1]).abs() < 0.02 && p[1] >= last[1] - 1e-6,
                "{p:?} {last:?}"
            );
            last = p;
        }
        assert!((last[1] - 8.0).abs() < 1e-4, "{last:?}");
        assert!(exec.is_idle());
    }
}

/// Arm, run a short program to its end: the period count it took.
fn run_program<R: controller_core::Real>(
    m: &mut Machine<Box<MachineMemory>, MachinePlanner, R>,
    w: &mut World,
) -> u32 {
    m.submit(Request::Arm);
    m.submit(Request::Run);
    for k in 1..=4u32 {
        let x = if k % 2 == 1 { 5.0 } else { 0.0 };
        m.submit(Request::Segment(Segment::line([x, 0.0, 0.0], 50.0, k)));
    }
    m.submit(Request::EndProgram);
    let mut k = 0;
    while !(m.status().program_done && m.servo().state() == ServoState::Idle) {
        m.period(w);
        w.advance();
        k += 1;
        assert!(k < 100_000, "the program did not end");
    }
    k
}

#[test]
fn a_machine_from_a_servo_configuration_runs_as_the_one_from_its_tree() {
    let (mut a, mut wa) = machine();
    let s = settings();
    let mut wb = world(&s);
    let mut b: M = Machine::from_config(
        &s.servo_config(RATE_HZ).unwrap(),
        &s.planner_config(RATE_HZ),
        wb.counter_registers(),
        wb.counts(),
        Box::new(MachineMemory::BLANK),
    )
    .unwrap();
    assert_eq!(b.rate_hz(), RATE_HZ);
    assert_eq!(run_program(&mut a, &mut wa), run_program(&mut b, &mut wb));
    assert_eq!(a.status(), b.status());
    assert_eq!(a.servo().snapshot(), b.servo().snapshot());
}

#[test]
fn a_machine_runs_its_servo_in_f64_too() {
    let s = settings();
    let mut w = world(&s);
    let mut m: Machine<Box<MachineMemory>, MachinePlanner, f64> = Machine::new(
        &s,
        RATE_HZ,
        w.counter_registers(),
        w.counts(),
        Box::new(MachineMemory::BLANK),
    )
    .unwrap();
    run_program(&mut m, &mut w);
    let p = m.servo().snapshot().pos;
    assert!(
        p[0].abs() < 0.01,
        "it ends at the last segment's end, not {p:?}"
    );
}

#[test]
fn compensation_tables_arm_in_place_are_refused_while_armed_and_move_the_motor_by_the_trim() {
    use controller_core::axes::Axis;
    use controller_core::motion::compensation::{AxisCompensation, CompPoint};
    use controller_core::servo::ReconfigureError;
    let (mut m, mut w) = machine();
    let pts = [
        CompPoint {
            nominal_mm: -100.0,
            fwd_trim_mm: 0.010,
            rev_trim_mm: -0.010,
        },
        CompPoint {
            nominal_mm: 100.0,
            fwd_trim_mm: 0.030,
            rev_trim_mm: 0.010,
        },
    ];
    let c = AxisCompensation::new(&pts, 0.0).unwrap();
    m.set_compensation(Axis::X, c).unwrap();
    let before = w.counts();
    m.submit(Request::Arm);
    periods(&mut m, &mut w, 3000);
    assert_eq!(m.servo().state(), ServoState::Idle);
    // arming holds where the motor is: nothing moved (the arm check's excursions are back)
    let after = w.counts();
    assert!((after[0] - before[0]).abs() <= 2, "{before:?} → {after:?}");
    // the tables are the machine's: not changed under power
    assert_eq!(
        m.set_compensation(Axis::X, AxisCompensation::NONE),
        Err(ReconfigureError::OutputsOn)
    );
    // forward to X 50: the motor lands at 50 + the forward trim there (25 µm); the
    // telemetry's reference stays the programmed position
    m.submit(Request::Run);
    m.submit(Request::Segment(Segment::line([50.0, 0.0, 0.0], 50.0, 1)));
    m.submit(Request::EndProgram);
    let mut k = 0;
    while !(m.status().program_done && m.servo().state() == ServoState::Idle) {
        periods(&mut m, &mut w, 100);
        k += 100;
        assert!(k < 100_000, "the program did not end");
    }
    periods(&mut m, &mut w, 2000);
    let snap = m.servo().snapshot();
    assert!(
        (snap.reference[0] - 50.0).abs() < 1e-4,
        "{:?}",
        snap.reference
    );
    assert!((snap.pos[0] - 50.025).abs() < 0.002, "{:?}", snap.pos);
    assert!(!m.servo().faults().any());
}

/// The transfer of a table over the link: `Request::CompBegin`, `CompPoints` in parts,
/// `CompCommit`, read back with `CompRead`, as `gantry comp load` sends it.
fn comp_requests(
    axis: u8,
    pts: &[controller_core::motion::compensation::CompPoint],
    backlash_mm: f32,
) -> Vec<Request> {
    use controller_core::machine::messages::COMP_CHUNK;
    let mut r = vec![Request::CompBegin {
        axis,
        points: pts.len() as u16,
        backlash_mm,
        rate_mm_s: 20.0,
        accel_mm_s2: 5000.0,
    }];
    for (k, part) in pts.chunks(COMP_CHUNK).enumerate() {
        r.push(Request::CompPoints {
            first: (k * COMP_CHUNK) as u16,
            points: heapless::Vec::from_slice(part).unwrap(),
        });
    }
    r.push(Request::CompCommit);
    r
}

/// Execute `r` alone and return its outcome.
fn outcome(m: &mut M, w: &mut World, r: Request) -> Outcome {
    let before = m.executed();
    m.submit(r);
    periods(m, w, 1);
    assert_eq!(m.executed(), before + 1, "executed in its period");
    m.last().clone()
}

fn is_refused_with(o: &Outcome, text: &str) -> bool {
    matches!(o, Outcome::Refused(t) if t.contains(text))
}

#[test]
fn a_compensation_table_entered_over_the_link_is_the_table_entered_whole_and_reads_back() {
    use controller_core::machine::messages::CompChunk;
    use controller_core::motion::compensation::{AxisCompensation, CompPoint};
    let (mut m, mut w) = machine();
    // 37 points: parts of 8, the last one of 5
    let pts: Vec<CompPoint> = (0..37)
        .map(|i| CompPoint {
            nominal_mm: -180.0 + 10.0 * i as f32,
            fwd_trim_mm: 0.015 * ((i as f32) * 0.4).sin(),
            rev_trim_mm: 0.015 * ((i as f32) * 0.4).sin() - 0.003,
        })
        .collect();
    for r in comp_requests(1, &pts, 0.020) {
        assert_eq!(outcome(&mut m, &mut w, r), Outcome::Done);
    }
    let whole = AxisCompensation::with_limits(&pts, 0.020, 20.0, 5000.0).unwrap();
    assert_eq!(*m.compensation().axis(1), whole, "bit for bit");
    assert!(m.compensation().axis(0).is_none() && m.compensation().axis(2).is_none());
    assert_eq!(m.status().comp, 0b010);
    // read back, 6 points at a time
    let mut back = Vec::new();
    loop {
        let o = outcome(
            &mut m,
            &mut w,
            Request::CompRead {
                axis: 1,
                first: back.len() as u16,
            },
        );
        let Outcome::Comp(CompChunk {
            axis: 1,
            total: 37,
            backlash_mm,
            points,
            ..
        }) = o
        else {
            panic!("{o:?}")
        };
        assert_eq!(backlash_mm, 0.020);
        if points.is_empty() {
            break;
        }
        back.extend(points);
    }
    assert_eq!(back.len(), 37);
    for (i, p) in back.iter().enumerate() {
        assert_eq!(Some(*p), whole.point(i));
        assert!((p.fwd_trim_mm - pts[i].fwd_trim_mm).abs() <= 0.5e-4 + 1e-7);
    }
    // an empty transfer clears the axis
    for r in comp_requests(1, &[], 0.0) {
        assert_eq!(outcome(&mut m, &mut w, r), Outcome::Done);
    }
    assert_eq!(m.status().comp, 0);
}

#[test]
fn a_compensation_transfer_refuses_bad_parts_and_commits_only_with_the_outputs_off() {
    use controller_core::motion::compensation::CompPoint;
    let (mut m, mut w) = machine();
    let p = |n: f32, t: f32| CompPoint {
        nominal_mm: n,
        fwd_trim_mm: t,
        rev_trim_mm: t,
    };
    let pts = [p(0.0, 0.01), p(50.0, 0.02), p(100.0, 0.0)];
    let points = |first: u16, ps: &[CompPoint]| Request::CompPoints {
        first,
        points: heapless::Vec::from_slice(ps).unwrap(),
    };
    // nothing under way
    let o = outcome(&mut m, &mut w, points(0, &pts));
    assert!(is_refused_with(&o, "no table transfer under way"), "{o:?}");
    let o = outcome(&mut m, &mut w, Request::CompCommit);
    assert!(is_refused_with(&o, "no table transfer under way"), "{o:?}");
    // a bad axis, a bad backlash
    let mut begin = comp_requests(3, &pts, 0.0).remove(0);
    let o = outcome(&mut m, &mut w, begin.clone());
    assert!(is_refused_with(&o, "axis must be 0, 1 or 2"), "{o:?}");
    if let Request::CompBegin {
        axis, backlash_mm, ..
    } = &mut begin
    {
        *axis = 0;
        *backlash_mm = 2.0;
    }
    let o = outcome(&mut m, &mut w, begin.clone());
    assert!(is_refused_with(&o, "backlash"), "{o:?}");
    // a good begin; parts out of order, not increasing, not finite, too large: refused
    let reqs = comp_requests(0, &pts, 0.01);
    assert_eq!(outcome(&mut m, &mut w, reqs[0].clone()), Outcome::Done);
    let o = outcome(&mut m, &mut w, points(1, &pts[1..]));
    assert!(is_refused_with(&o, "out of order"), "{o:?}");
    let o = outcome(&mut m, &mut w, points(0, &[pts[1], pts[0]]));
    assert!(is_refused_with(&o, "increase strictly"), "{o:?}");
    let o = outcome(&mut m, &mut w, points(0, &[p(0.0, f32::NAN)]));
    assert!(is_refused_with(&o, "not finite"), "{o:?}");
    let o = outcome(&mut m, &mut w, points(0, &[p(0.0, 5.0)]));
    assert!(is_refused_with(&o, "trim beyond"), "{o:?}");
    // a commit short of points: refused, the transfer stays
    assert_eq!(outcome(&mut m, &mut w, points(0, &pts[..2])), Outcome::Done);
    let o = outcome(&mut m, &mut w, Request::CompCommit);
    assert!(is_refused_with(&o, "fewer points"), "{o:?}");
    assert_eq!(outcome(&mut m, &mut w, points(2, &pts[2..])), Outcome::Done);
    // armed: the commit is refused and changes nothing
    m.submit(Request::Arm);
    periods(&mut m, &mut w, 3000);
    assert_eq!(m.servo().state(), ServoState::Idle);
    let o = outcome(&mut m, &mut w, Request::CompCommit);
    assert!(is_refused_with(&o, "outputs are on"), "{o:?}");
    assert_eq!(m.status().comp, 0);
    // disarmed: taken
    m.submit(Request::Disarm);
    let mut k = 0;
    while m.servo().state().drives() || m.servo().switching_off() {
        periods(&mut m, &mut w, 100);
        k += 100;
        assert!(k < 10_000, "the disarm did not end");
    }
    assert_eq!(outcome(&mut m, &mut w, Request::CompCommit), Outcome::Done);
    assert_eq!(m.status().comp, 0b001);
    // a new session drops a transfer under way: its commit is refused
    let reqs = comp_requests(2, &pts, 0.0);
    for r in &reqs[..reqs.len() - 1] {
        assert_eq!(outcome(&mut m, &mut w, r.clone()), Outcome::Done);
    }
    m.session_started();
    // (the session's link-up command goes to the servo first; the commit waits for it)
    periods(&mut m, &mut w, 1);
    let o = outcome(&mut m, &mut w, Request::CompCommit);
    assert!(is_refused_with(&o, "no table transfer under way"), "{o:?}");
    assert_eq!(m.status().comp, 0b001);
}

/// A loop measurement needs the laws holding the axis: from Disabled it is refused and
/// nothing starts; a fourth axis is refused by name.
#[test]
fn a_loop_measurement_is_refused_by_name_off_the_laws_or_off_the_axes() {
    let (mut m, mut w) = machine();
    assert_eq!(m.servo().state(), ServoState::Disabled);
    let o = outcome(
        &mut m,
        &mut w,
        Request::MeasureLoop {
            axis: 3,
            window_mm: Some([-50.0, 50.0]),
        },
    );
    assert!(is_refused_with(&o, "loop: axis must be 0, 1 or 2"), "{o:?}");
    let o = outcome(
        &mut m,
        &mut w,
        Request::MeasureLoop {
            axis: 1,
            window_mm: Some([-50.0, 50.0]),
        },
    );
    assert!(
        is_refused_with(&o, "not allowed in the current state"),
        "{o:?}"
    );
    periods(&mut m, &mut w, 100);
    assert_eq!(m.servo().state(), ServoState::Disabled);
    assert!(m.servo().response_outcome().is_none());
}
