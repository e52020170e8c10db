//! The settings tab: every key of the machine's settings tree (the registry
//! `controller_core::settings::keys`) grouped by its dotted prefix (`axis` › `x` › `law`),
//! with its value, unit, range, apply class and one-line doc, an edit field per key, and
//! the same checks `gantry settings set` / `import` make before anything is sent: the
//! key's own parser, its range, then the whole tree's rules (`Settings::stage_text` and
//! `Settings::validate_change`, exactly as `host_sim::cli::import_settings` does). The
//! pending edits go to the machine as one transaction (`Command::SetSettings`), which it
//! takes all or none; its refusal lands in the log.

use crate::app::GantryApp;
use crate::session::Command;
use controller_core::machine::messages::MachineState;
use controller_core::settings::keys::{find, keys, Key};
use controller_core::settings::{Range, SetError, Settings, Value, FACTORY};
use egui::{Color32, RichText};
use std::collections::BTreeMap;

/// Red of the error texts (the read-out's fault red).
const ERROR_RED: Color32 = Color32::from_rgb(220, 50, 47);
/// Colour of a value that differs from the factory's.
const CHANGED_GOLD: Color32 = Color32::from_rgb(181, 137, 0);

/// The tab's state: the machine's values as last read, the user's pending edits, and the
/// result of checking them.
#[derive(Debug, Default)]
pub struct SettingsPanel {
    /// `key → text` as the machine last reported them (keys of absent values left out).
    pub values: Vec<(String, String)>,
    /// Pending edits, `key → text` (only keys whose text differs from the machine's).
    pub edits: BTreeMap<String, String>,
    /// Keys whose name or doc contain this (case-insensitive) are shown.
    pub filter: String,
    /// Show only the keys whose value differs from the factory's.
    pub only_changed: bool,
    /// The edits' check, redone whenever they or the values change.
    pub check: Check,
    /// The machine's control rate, Hz, as it reported it on connecting: the edits are
    /// checked at it (the servo's cross-field limits depend on the period).
    pub rate_hz: u32,
}

/// What the local check found.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Check {
    /// Errors by key (the text names the key, as the machine's would).
    pub by_key: BTreeMap<String, String>,
    /// An error that names no key (the machine's own values do not form a valid tree).
    pub general: Option<String>,
}

impl Check {
    pub fn is_ok(&self) -> bool {
        self.by_key.is_empty() && self.general.is_none()
    }
}

impl SettingsPanel {
    /// The machine's values (after a read or a change): edits that now equal the
    /// machine's value are dropped, the rest are checked again against the new values.
    pub fn set_values(&mut self, all: Vec<(String, String)>) {
        self.values = all;
        let values = &self.values;
        self.edits
            .retain(|k, v| values.iter().find(|(n, _)| n == k).map(|(_, t)| t) != Some(v));
        self.recheck();
    }

    /// The machine's text of `key`.
    pub fn current(&self, key: &str) -> Option<&str> {
        self.values
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Set (or, when it equals the machine's value, drop) the edit of `key`, and check.
    pub fn edit(&mut self, key: &str, text: String) {
        if self.current(key) == Some(text.as_str()) {
            self.edits.remove(key);
        } else {
            self.edits.insert(key.to_string(), text);
        }
        self.recheck();
    }

    /// Forget every pending edit.
    pub fn revert(&mut self) {
        self.edits.clear();
        self.recheck();
    }

    fn recheck(&mut self) {
        self.check = check_edits(&self.values, &self.edits, self.rate_hz);
    }

    /// The edits as one transaction, in the registry's key order (so that
    /// `axis.x.model.known = true` comes before the model's parameters it makes settable).
    pub fn changes(&self) -> Vec<(String, String)> {
        ordered(&self.edits)
    }
}

/// `edits` in the registry's key order.
fn ordered(edits: &BTreeMap<String, String>) -> Vec<(String, String)> {
    let mut out: Vec<(usize, String, String)> = edits
        .iter()
        .map(|(k, v)| {
            let at = keys().position(|key| key.name == k).unwrap_or(usize::MAX);
            (at, k.clone(), v.clone())
        })
        .collect();
    out.sort();
    out.into_iter().map(|(_, k, v)| (k, v)).collect()
}

/// The machine's tree rebuilt from its `key → text` values (as `import_settings` does).
pub fn tree_of(values: &[(String, String)], rate_hz: u32) -> Result<Settings, String> {
    let mut parsed: Vec<(&str, Value)> = Vec::with_capacity(values.len());
    for (k, v) in values {
        let key = find(k).map_err(|e| e.to_string())?;
        parsed.push((key.name, key.parse(v).map_err(|e| e.to_string())?));
    }
    let mut tree = FACTORY;
    tree.set_all(&parsed, rate_hz)
        .map_err(|e| format!("the machine's own settings do not validate: {e}"))?;
    Ok(tree)
}

/// The key an error names.
fn error_key(e: &SetError) -> Option<&str> {
    match e {
        SetError::Unknown(k) => Some(k.as_str()),
        SetError::WrongType { key, .. }
        | SetError::OutOfRange { key, .. }
        | SetError::NoModel { key }
        | SetError::Rejected { key, .. } => Some(key),
        SetError::Tree(_) => None,
    }
}

/// `gantry settings set`'s checks of `edits` against the machine's `values`: each edit
/// staged (key's parser, type, range) in key order on the machine's tree, then, when all
/// of them pass, the whole changed tree validated at `rate_hz` (the servo's cross-field
/// rules); every error filed under the key it names.
pub fn check_edits(
    values: &[(String, String)],
    edits: &BTreeMap<String, String>,
    rate_hz: u32,
) -> Check {
    let mut check = Check::default();
    if edits.is_empty() {
        return check;
    }
    // no values read yet: check against the factory tree (the machine will check again)
    let base = if values.is_empty() {
        Ok(FACTORY)
    } else {
        tree_of(values, rate_hz)
    };
    let base = match base {
        Ok(t) => t,
        Err(e) => {
            check.general = Some(e);
            return check;
        }
    };
    let mut next = base;
    for (k, text) in ordered(edits) {
        if let Err(e) = next.stage_text(&k, &text) {
            check.by_key.insert(k, e.to_string());
        }
    }
    if check.by_key.is_empty() {
        if let Err(e) = next.validate_change(&base, rate_hz) {
            match error_key(&e) {
                Some(k) => {
                    check.by_key.insert(k.to_string(), e.to_string());
                }
                None => check.general = Some(e.to_string()),
            }
        }
    }
    check
}

/// The value of `key` in the factory tree, as text (`None`: a model parameter of an axis
/// the factory tree has no model for).
pub fn factory_text(key: &Key) -> Option<String> {
    key.get(&FACTORY).map(|v| v.to_string())
}

/// `text` (the machine's) is not the factory's value of `key` (compared as values, so
/// `1` and `1.0` are the same).
pub fn differs_from_factory(key: &Key, text: &str) -> bool {
    match (key.parse(text), key.get(&FACTORY)) {
        (Ok(v), Some(f)) => !v.same(&f),
        (Ok(_), None) => true,
        (Err(_), _) => false,
    }
}

/// A node of the key tree: the keys ending here (their last segment is the leaf) and the
/// groups below, both in the registry's order.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Group {
    /// This group's segment (`x` in `axis.x`); empty at the root.
    pub name: String,
    /// The keys whose prefix is exactly this group's path.
    pub keys: Vec<&'static str>,
    pub groups: Vec<Group>,
}

impl Group {
    /// Every key under this group, depth first.
    pub fn all_keys(&self) -> Vec<&'static str> {
        let mut out = self.keys.clone();
        for g in &self.groups {
            out.extend(g.all_keys());
        }
        out
    }
}

/// The keys `names` grouped by their dotted prefixes (`axis.x.law.kind` under
/// `axis` › `x` › `law`), order of first appearance kept.
pub fn group(names: impl IntoIterator<Item = &'static str>) -> Group {
    let mut root = Group::default();
    for name in names {
        let mut node = &mut root;
        let mut parts: Vec<&str> = name.split('.').collect();
        parts.pop(); // the leaf
        for p in parts {
            let i = match node.groups.iter().position(|g| g.name == p) {
                Some(i) => i,
                None => {
                    node.groups.push(Group {
                        name: p.to_string(),
                        ..Group::default()
                    });
                    node.groups.len() - 1
                }
            };
            node = &mut node.groups[i];
        }
        node.keys.push(name);
    }
    root
}

/// The key's last segment (`kind` of `axis.x.law.kind`).
fn leaf(name: &str) -> &str {
    name.rsplit('.').next().unwrap_or(name)
}

/// Whether `key` passes the tab's filter.
fn shown(panel: &SettingsPanel, key: &Key) -> bool {
    if panel.only_changed {
        match panel.current(key.name) {
            Some(t) if differs_from_factory(key, t) => {}
            _ => return false,
        }
    }
    let f = panel.filter.trim().to_lowercase();
    f.is_empty() || key.name.to_lowercase().contains(&f) || key.doc.to_lowercase().contains(&f)
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    let state = app.live.status.as_ref().map(|s| s.state);
    let free = app.busy.is_none() && app.lost.is_none() && app.session.is_some();
    ui.horizontal(|ui| {
        let n = app.settings.edits.len();
        let ok = app.settings.check.is_ok();
        if ui
            .add_enabled(
                free && n > 0 && ok,
                egui::Button::new(format!("Apply ({n})")),
            )
            .on_hover_text(
                "send every pending edit as one transaction: the machine checks them again \
                 and takes all or none (its refusal appears in the log); changes that \
                 need the outputs off are refused while armed",
            )
            .on_disabled_hover_text(if n == 0 {
                "no pending edits"
            } else if !ok {
                "fix the errors in red first"
            } else {
                "the machine is busy or not connected"
            })
            .clicked()
        {
            let changes = app.settings.changes();
            app.send(Command::SetSettings(changes));
        }
        if ui
            .add_enabled(n > 0, egui::Button::new("Revert"))
            .on_hover_text("forget the pending edits")
            .clicked()
        {
            app.settings.revert();
        }
        if ui
            .add_enabled(free, egui::Button::new("Reload"))
            .on_hover_text("read every setting from the machine again")
            .clicked()
        {
            app.send(Command::ReadSettings);
        }
        // the machine refuses to write its flash with the outputs on (it stalls the loop)
        let outputs_off = matches!(state, Some(MachineState::Disabled | MachineState::Fault));
        if ui
            .add_enabled(free && outputs_off, egui::Button::new("Save to flash"))
            .on_hover_text(
                "store the machine's current settings in its flash (kept across power \
                 cycles); the machine refuses while armed: disarm first",
            )
            .on_disabled_hover_text(
                "the machine refuses to save while armed (writing flash stalls the control \
                 loop): disarm first",
            )
            .clicked()
        {
            app.send(Command::SaveSettings);
        }
        ui.separator();
        ui.label("Filter");
        ui.add(
            egui::TextEdit::singleline(&mut app.settings.filter)
                .hint_text("key or word")
                .desired_width(160.0),
        );
        ui.checkbox(&mut app.settings.only_changed, "only changed from factory")
            .on_hover_text("show only the values that differ from the factory settings");
    });
    ui.label(
        RichText::new(format!(
            "{} settings read; gold values differ from the factory's; hover a name for what it is",
            app.settings.values.len()
        ))
        .weak(),
    );
    if let Some(e) = &app.settings.check.general {
        ui.label(RichText::new(e).color(ERROR_RED));
    }
    ui.separator();
    editor(&mut app.settings, ui);
}

/// The key tree with its edit fields (no machine needed: the headless tests show it).
pub fn editor(panel: &mut SettingsPanel, ui: &mut egui::Ui) {
    let root = group(keys().map(|k| k.name));
    let filtering = !panel.filter.trim().is_empty() || panel.only_changed;
    egui::ScrollArea::vertical()
        .auto_shrink([false, false])
        .show(ui, |ui| {
            for g in &root.groups {
                show_group(panel, ui, g, g.name.clone(), filtering);
            }
            show_keys(panel, ui, &root.keys, "");
        });
}

/// One group: a collapsing header (opened while filtering) holding its keys and groups.
fn show_group(
    panel: &mut SettingsPanel,
    ui: &mut egui::Ui,
    g: &Group,
    path: String,
    filtering: bool,
) {
    let visible: Vec<&'static str> = g
        .all_keys()
        .into_iter()
        .filter(|k| find(k).is_ok_and(|key| shown(panel, &key)))
        .collect();
    if visible.is_empty() {
        return;
    }
    let pending = visible
        .iter()
        .filter(|k| panel.edits.contains_key(**k))
        .count();
    let errors = visible
        .iter()
        .filter(|k| panel.check.by_key.contains_key(**k))
        .count();
    let mut title = RichText::new(format!("{}  ({})", g.name, visible.len()));
    if errors > 0 {
        title = RichText::new(format!(
            "{}  ({}, {errors} error(s))",
            g.name,
            visible.len()
        ))
        .color(ERROR_RED);
    } else if pending > 0 {
        title =
            RichText::new(format!("{}  ({}, {pending} edited)", g.name, visible.len())).strong();
    }
    // the first axis opens by itself: the operator sees what a key row looks like
    let mut header = egui::CollapsingHeader::new(title)
        .id_salt(&path)
        .default_open(path == "axis" || path == "axis.x");
    if filtering || errors > 0 {
        header = header.open(Some(true));
    }
    header.show(ui, |ui| {
        show_keys(panel, ui, &g.keys, &path);
        for sub in &g.groups {
            show_group(panel, ui, sub, format!("{path}.{}", sub.name), filtering);
        }
    });
}

/// The keys of one group as a grid: name, edit field, unit, range, factory mark, error.
fn show_keys(panel: &mut SettingsPanel, ui: &mut egui::Ui, names: &[&'static str], path: &str) {
    let shown_keys: Vec<Key> = names
        .iter()
        .filter_map(|n| find(n).ok())
        .filter(|k| shown(panel, k))
        .collect();
    if shown_keys.is_empty() {
        return;
    }
    egui::Grid::new(("settings-keys", path))
        .num_columns(5)
        .striped(true)
        .show(ui, |ui| {
            for key in shown_keys {
                key_row(panel, ui, &key);
                ui.end_row();
            }
        });
}

fn key_row(panel: &mut SettingsPanel, ui: &mut egui::Ui, key: &Key) {
    let current = panel.current(key.name).map(str::to_string);
    let changed = current
        .as_deref()
        .is_some_and(|t| differs_from_factory(key, t));
    let factory = factory_text(key).unwrap_or_else(|| "no model".into());
    let mut name = RichText::new(leaf(key.name)).monospace();
    if changed {
        name = name.color(CHANGED_GOLD);
    }
    if panel.edits.contains_key(key.name) {
        name = name.strong();
    }
    let hover = format!(
        "{}\n\n{}\nunit: {}\nrange: {}\napplies: {}\nfactory: {}\nmachine: {}",
        key.name,
        key.doc,
        if key.unit.is_empty() { "—" } else { key.unit },
        key.range,
        key.apply.name(),
        factory,
        current.as_deref().unwrap_or("— (no model)"),
    );
    let name_id = ui.label(name).on_hover_text(hover).id;
    // the edit: the pending text, else the machine's value
    let mut text = panel
        .edits
        .get(key.name)
        .cloned()
        .or_else(|| current.clone())
        .unwrap_or_default();
    let before = text.clone();
    match key.range {
        Range::Bool => {
            let mut b = text.trim() == "true";
            // (only a click makes an edit: an unread value is not "false")
            if ui.checkbox(&mut b, "").labelled_by(name_id).changed() {
                text = b.to_string();
            }
        }
        Range::Choice(names) => {
            egui::ComboBox::from_id_salt(("setting", key.name))
                .selected_text(text.clone())
                .show_ui(ui, |ui| {
                    for n in names {
                        ui.selectable_value(&mut text, n.to_string(), *n);
                    }
                });
        }
        Range::F32 { .. } | Range::U32 { .. } => {
            // (sized: a grid cell would otherwise shrink it to its first frame's width)
            ui.add_sized(
                [110.0, ui.spacing().interact_size.y],
                egui::TextEdit::singleline(&mut text).hint_text(if current.is_none() {
                    "no model"
                } else {
                    ""
                }),
            )
            .labelled_by(name_id);
        }
    }
    if text != before {
        panel.edit(key.name, text);
    }
    ui.label(RichText::new(key.unit).weak());
    let mut info = format!("{}", key.range);
    if changed {
        info.push_str(&format!("  (factory {factory})"));
    }
    ui.label(RichText::new(info).weak().small());
    match panel.check.by_key.get(key.name) {
        Some(e) => {
            ui.label(RichText::new(e).color(ERROR_RED));
        }
        None if panel.edits.contains_key(key.name) => {
            ui.label(RichText::new(format!("was {}", current.as_deref().unwrap_or("—"))).weak());
        }
        None => {
            ui.label("");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// The rate the project's machines run at (what they report on connecting).
    pub(super) const RATE_HZ: u32 = 10_000;

    /// The factory tree's values, as the machine would report them.
    fn factory_values() -> Vec<(String, String)> {
        FACTORY
            .list()
            .filter_map(|(k, v)| Some((k.name.to_string(), v?.to_string())))
            .collect()
    }

    #[test]
    fn the_tree_holds_every_key_exactly_once_under_its_prefix() {
        let all: Vec<&'static str> = keys().map(|k| k.name).collect();
        let root = group(all.iter().copied());
        let grouped = root.all_keys();
        assert_eq!(grouped.len(), all.len());
        let unique: BTreeSet<&str> = grouped.iter().copied().collect();
        assert_eq!(unique.len(), all.len(), "a key appears twice");
        assert_eq!(unique, all.iter().copied().collect());
        // axis › x › law holds axis.x.law.kind
        let axis = root.groups.iter().find(|g| g.name == "axis").unwrap();
        assert_eq!(
            axis.groups
                .iter()
                .map(|g| g.name.as_str())
                .collect::<Vec<_>>(),
            ["x", "y", "z"]
        );
        let law = axis.groups[0]
            .groups
            .iter()
            .find(|g| g.name == "law")
            .unwrap();
        assert!(law.keys.contains(&"axis.x.law.kind"), "{law:?}");
        // and every key sits in the group its dotted prefix names
        fn walk(g: &Group, prefix: &str) {
            for k in &g.keys {
                let p = k.rsplit_once('.').map_or("", |(p, _)| p);
                assert_eq!(p, prefix, "{k}");
            }
            for s in &g.groups {
                let path = if prefix.is_empty() {
                    s.name.clone()
                } else {
                    format!("{prefix}.{}", s.name)
                };
                walk(s, &path);
            }
        }
        walk(&root, "");
    }

    #[test]
    fn an_out_of_range_edit_is_flagged_naming_its_key_and_a_valid_one_is_not() {
        let values = factory_values();
        let mut edits = BTreeMap::new();
        // following error: range [0.001, 100] mm
        edits.insert("axis.x.following_error_mm".to_string(), "250".to_string());
        let c = check_edits(&values, &edits, RATE_HZ);
        let e = c.by_key.get("axis.x.following_error_mm").unwrap();
        assert!(
            e.contains("axis.x.following_error_mm") && e.contains("250") && e.contains("100"),
            "{e}"
        );
        edits.insert("axis.x.following_error_mm".to_string(), "0.5".to_string());
        let c = check_edits(&values, &edits, RATE_HZ);
        assert!(c.is_ok(), "{c:?}");
        // not a number: the key's own parser says so
        edits.insert("axis.x.following_error_mm".to_string(), "0,5".to_string());
        let c = check_edits(&values, &edits, RATE_HZ);
        let e = c.by_key.get("axis.x.following_error_mm").unwrap();
        assert!(e.contains("expected"), "{e}");
        // a choice that is not one
        let mut edits = BTreeMap::new();
        edits.insert("axis.y.law.kind".to_string(), "fuzzy".to_string());
        let c = check_edits(&values, &edits, RATE_HZ);
        assert!(c.by_key.contains_key("axis.y.law.kind"), "{c:?}");
    }

    #[test]
    fn a_cross_field_rule_is_checked_on_the_whole_tree() {
        // travel min above max: each in range alone, the tree refuses it
        let values = factory_values();
        let min = FACTORY.get("axis.x.travel.min_mm").unwrap().to_string();
        let max: f32 = FACTORY
            .get("axis.x.travel.max_mm")
            .unwrap()
            .to_string()
            .parse()
            .unwrap();
        let mut edits = BTreeMap::new();
        edits.insert(
            "axis.x.travel.min_mm".to_string(),
            format!("{}", max + 10.0),
        );
        let c = check_edits(&values, &edits, RATE_HZ);
        assert!(!c.is_ok(), "min {min} -> {} accepted", max + 10.0);
        let (k, e) = c.by_key.iter().next().unwrap();
        assert_eq!(k, "axis.x.travel.min_mm");
        assert!(e.contains("rejected"), "{e}");
    }

    #[test]
    fn an_edit_back_to_the_machines_value_is_no_edit_and_new_values_drop_met_edits() {
        let mut p = SettingsPanel {
            rate_hz: RATE_HZ,
            ..SettingsPanel::default()
        };
        p.set_values(factory_values());
        let k = "axis.z.jog.speed_max_mm_s";
        let now = p.current(k).unwrap().to_string();
        assert_ne!(now, "12.5");
        p.edit(k, "12.5".into());
        assert_eq!(p.changes(), [(k.to_string(), "12.5".to_string())]);
        p.edit(k, now.clone());
        assert!(p.edits.is_empty());
        p.edit(k, "12.5".into());
        let mut v = factory_values();
        for (n, t) in v.iter_mut() {
            if n == k {
                *t = "12.5".into();
            }
        }
        p.set_values(v);
        assert!(p.edits.is_empty(), "the machine took it: nothing pending");
    }

    #[test]
    fn changes_go_in_key_order_known_before_the_models_values() {
        let mut edits = BTreeMap::new();
        edits.insert("axis.x.model.inertia".to_string(), "0.05".to_string());
        edits.insert("axis.x.model.known".to_string(), "true".to_string());
        edits.insert("axis.x.following_error_mm".to_string(), "0.5".to_string());
        let order: Vec<String> = ordered(&edits).into_iter().map(|(k, _)| k).collect();
        let pos = |k: &str| order.iter().position(|o| o == k).unwrap();
        assert!(pos("axis.x.model.known") < pos("axis.x.model.inertia"));
    }

    #[test]
    fn factory_values_are_not_marked_and_a_changed_one_is() {
        let k = find("axis.x.following_error_mm").unwrap();
        let f = factory_text(&k).unwrap();
        assert!(!differs_from_factory(&k, &f));
        let other: f32 = f.parse::<f32>().unwrap() * 2.0;
        assert!(differs_from_factory(&k, &other.to_string()));
    }
}

/// The editor driven headless through its accessibility tree (egui_kittest): what an
/// operator types, and what the tab then shows.
#[cfg(test)]
mod ui_tests {
    use super::*;
    use egui_kittest::kittest::Queryable;
    use egui_kittest::Harness;

    fn panel() -> SettingsPanel {
        let mut p = SettingsPanel {
            rate_hz: super::tests::RATE_HZ,
            ..SettingsPanel::default()
        };
        p.set_values(
            FACTORY
                .list()
                .filter_map(|(k, v)| Some((k.name.to_string(), v?.to_string())))
                .collect(),
        );
        p
    }

    #[test]
    fn typing_an_out_of_range_value_shows_the_error_naming_the_key() {
        let mut h = Harness::new_ui_state(|ui, p: &mut SettingsPanel| editor(p, ui), panel());
        h.run();
        // axis › x is open: its following error field, labelled by its name
        let field = h.get_by_label("following_error_mm");
        field.focus();
        field.type_text("250");
        h.run();
        assert_eq!(
            h.state()
                .edits
                .get("axis.x.following_error_mm")
                .map(String::as_str),
            Some("1250"),
            "typed after the factory's 1 mm"
        );
        h.get_by_label_contains("axis.x.following_error_mm: 1250 is outside the allowed range");
        assert!(!h.state().check.is_ok());
    }

    #[test]
    fn a_valid_edit_shows_no_error_and_no_edit_appears_before_a_click() {
        let mut h = Harness::new_ui_state(|ui, p: &mut SettingsPanel| editor(p, ui), panel());
        h.run();
        assert!(h.state().edits.is_empty(), "{:?}", h.state().edits);
        let field = h.get_by_label("min_ferror_mm");
        field.focus();
        field.type_text("5");
        h.run();
        assert_eq!(
            h.state()
                .edits
                .get("axis.x.min_ferror_mm")
                .map(String::as_str),
            Some("0.15")
        );
        assert!(h.state().check.is_ok(), "{:?}", h.state().check);
        assert!(h
            .query_by_label_contains("outside the allowed range")
            .is_none());
    }
}
