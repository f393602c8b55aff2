//! The moments an artist asks for (`edits: [...]` in `pipeline.ron`), which stage 7 edits into
//! the patches they cover: people meeting at a point, an area filling, a drift, a whirl. Each
//! has a name (errors and the report use it), a place in world metres (x east, y north, as the
//! painted maps), a time or a window in the period, and optionally its weights.

use super::checks::{Check, Num, invalid, positive, require};
use serde::{Deserialize, Serialize};

/// One edit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Edit {
    pub name: String,
    pub kind: EditKind,
    /// R of the paper's eq. 6: how loosely the edit's target is held, in its kind's units
    /// squared (m^2, people^2/m^4, m^2/s^2, 1/s^2). Default: [`EditKind::default_r`].
    #[serde(default)]
    pub r: Option<f64>,
    /// Q_u, m^2/s^4: how freely walkers may leave the motion stages 3-6 planned for them (the
    /// model error's covariance). Default: [`DEFAULT_Q`].
    #[serde(default)]
    pub q: Option<f64>,
}

/// What an edit asks for. A window `(from, to)` is in seconds of the period: `from` in
/// [0, period), `to` after it and at most a period later; a window ending past the period
/// wraps round to its start (`(18, 22)` in a 20 s period is 18-20 s and 0-2 s).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum EditKind {
    /// `people` walkers (the nearest to `at` then) meet at `at` at `time_s`, standing round it
    /// `radius_m` from it (default: as close as their bodies allow).
    Meet {
        at: (f64, f64),
        time_s: f64,
        #[serde(default = "two")]
        people: u32,
        #[serde(default)]
        radius_m: Option<f64>,
    },
    /// The rectangle `(x0, y0, x1, y1)` holds `people_per_m2` over the window.
    Density {
        rect: (f64, f64, f64, f64),
        window_s: (f64, f64),
        people_per_m2: f64,
    },
    /// The crowd in the rectangle moves at `velocity_m_s` (east, north) over the window.
    Flow {
        rect: (f64, f64, f64, f64),
        window_s: (f64, f64),
        velocity_m_s: (f64, f64),
    },
    /// The crowd in the rectangle moves as the flow map `map` says (a PNG the size of the
    /// layers, in their convention: R = east, G = north, 128 = zero, A = weight; its path
    /// relative to `pipeline.ron`), a full-strength pixel at `speed_m_s`, over the window.
    /// Pixels of alpha under a half leave their place free.
    FlowMap {
        rect: (f64, f64, f64, f64),
        window_s: (f64, f64),
        map: std::path::PathBuf,
        speed_m_s: f64,
    },
    /// The crowd in the rectangle turns at `per_s` (the vorticity, 1/s: positive
    /// anticlockwise) over the window.
    Vorticity {
        rect: (f64, f64, f64, f64),
        window_s: (f64, f64),
        per_s: f64,
    },
}

fn two() -> u32 {
    2
}

/// The default Q_u, m^2/s^4: a walker may be pushed by about 1 m/s^2 for a few seconds before
/// the push costs as much as a missed target.
pub const DEFAULT_Q: f64 = 1.0;

/// The most walkers one meeting may gather.
pub const MAX_MEET_PEOPLE: u32 = 12;

/// The strongest whirl, 1/s: a full turn in about 3 s.
pub const MAX_VORTICITY: f64 = 2.0;

impl EditKind {
    pub fn name(&self) -> &'static str {
        match self {
            EditKind::Meet { .. } => "Meet",
            EditKind::Density { .. } => "Density",
            EditKind::Flow { .. } => "Flow",
            EditKind::FlowMap { .. } => "FlowMap",
            EditKind::Vorticity { .. } => "Vorticity",
        }
    }

    /// R when the edit gives none: a fifth of the target's own scale squared, so that a
    /// missed target weighs as much as a few seconds of 1 m/s^2 of push (Q).
    pub fn default_r(&self) -> f64 {
        match self {
            EditKind::Meet { .. } => 0.05,
            EditKind::Density { .. } => 0.01,
            EditKind::Flow { .. } | EditKind::FlowMap { .. } => 0.05,
            EditKind::Vorticity { .. } => 0.02,
        }
    }

    /// The window, seconds of the period (a meeting's is its instant).
    pub fn window(&self) -> (f64, f64) {
        match *self {
            EditKind::Meet { time_s, .. } => (time_s, time_s),
            EditKind::Density { window_s, .. }
            | EditKind::Flow { window_s, .. }
            | EditKind::FlowMap { window_s, .. }
            | EditKind::Vorticity { window_s, .. } => window_s,
        }
    }

    /// The place it covers, `(x0, y0, x1, y1)` m (a meeting's point, twice).
    pub fn rect(&self) -> (f64, f64, f64, f64) {
        match *self {
            EditKind::Meet { at, .. } => (at.0, at.1, at.0, at.1),
            EditKind::Density { rect, .. }
            | EditKind::Flow { rect, .. }
            | EditKind::FlowMap { rect, .. }
            | EditKind::Vorticity { rect, .. } => rect,
        }
    }
}

/// What the edits are checked against: the period and the limits other settings set.
pub struct EditLimits {
    pub period_s: f64,
    /// `optimize.rho_max`, people per m^2.
    pub rho_max: f64,
    /// `match.max_speed`, m/s.
    pub max_speed: f64,
}

/// Refuses an edit no stage can make, naming it and its field (`edits[1].kind.window_s`).
pub fn validate_edits(edits: &[Edit], limits: &EditLimits) -> Check {
    for (k, edit) in edits.iter().enumerate() {
        let at = |field: &str| format!("edits[{k}].{field}");
        let named = |what: String| format!("(edit `{}`) {what}", edit.name);
        if edit.name.trim().is_empty() {
            return Err(invalid(
                &at("name"),
                "is empty; expected a name the report and errors can use",
            ));
        }
        if let Some(other) = edits[..k].iter().position(|e| e.name == edit.name) {
            return Err(invalid(
                &at("name"),
                format!(
                    "is `{}`, the name of edits[{other}] too; expected a name of its own",
                    edit.name
                ),
            ));
        }
        for (field, value) in [("r", edit.r), ("q", edit.q)] {
            if let Some(v) = value {
                positive(&at(field), v, &named("a positive weight".into()))?;
            }
        }
        validate_kind(&edit.kind, limits, &at, &named)?;
    }
    Ok(())
}

fn validate_kind(
    kind: &EditKind,
    limits: &EditLimits,
    at: &dyn Fn(&str) -> String,
    named: &dyn Fn(String) -> String,
) -> Check {
    let period = limits.period_s;
    match *kind {
        EditKind::Meet {
            at: point,
            time_s,
            people,
            radius_m,
        } => {
            require(
                point.0.is_finite() && point.1.is_finite(),
                &at("kind.at"),
                format!("({}, {})", Num(point.0), Num(point.1)),
                &named("a point in world metres".into()),
            )?;
            require(
                (0.0..period).contains(&time_s),
                &at("kind.time_s"),
                Num(time_s),
                &named(format!("a time in the period, from 0 to {} s", Num(period))),
            )?;
            require(
                (1..=MAX_MEET_PEOPLE).contains(&people),
                &at("kind.people"),
                people,
                &named(format!("from 1 to {MAX_MEET_PEOPLE} walkers")),
            )?;
            if let Some(r) = radius_m {
                positive(
                    &at("kind.radius_m"),
                    r,
                    &named("a positive radius in metres".into()),
                )?;
            }
            Ok(())
        }
        EditKind::Density {
            rect,
            window_s,
            people_per_m2,
        } => {
            validate_area(rect, window_s, period, at, named)?;
            require(
                people_per_m2.is_finite()
                    && people_per_m2 >= 0.0
                    && people_per_m2 <= limits.rho_max,
                &at("kind.people_per_m2"),
                Num(people_per_m2),
                &named(format!(
                    "a density from 0 to `optimize.rho_max` ({} people per m2: patches hold no \
                     more, so no edit can fill one past it)",
                    Num(limits.rho_max)
                )),
            )
        }
        EditKind::Flow {
            rect,
            window_s,
            velocity_m_s: (vx, vy),
        } => {
            validate_area(rect, window_s, period, at, named)?;
            let speed = vx.hypot(vy);
            require(
                speed.is_finite() && speed <= limits.max_speed,
                &at("kind.velocity_m_s"),
                format!("({}, {})", Num(vx), Num(vy)),
                &named(format!(
                    "a velocity no faster than `match.max_speed` ({} m/s)",
                    Num(limits.max_speed)
                )),
            )
        }
        EditKind::FlowMap {
            rect,
            window_s,
            ref map,
            speed_m_s,
        } => {
            validate_area(rect, window_s, period, at, named)?;
            require(
                !map.as_os_str().is_empty(),
                &at("kind.map"),
                "\"\"",
                &named("the path of an RGBA flow-map PNG, relative to pipeline.ron".into()),
            )?;
            require(
                speed_m_s.is_finite() && speed_m_s > 0.0 && speed_m_s <= limits.max_speed,
                &at("kind.speed_m_s"),
                Num(speed_m_s),
                &named(format!(
                    "the speed of a full-strength pixel, above 0 and no faster than \
                     `match.max_speed` ({} m/s)",
                    Num(limits.max_speed)
                )),
            )
        }
        EditKind::Vorticity {
            rect,
            window_s,
            per_s,
        } => {
            validate_area(rect, window_s, period, at, named)?;
            require(
                per_s.is_finite() && per_s != 0.0 && per_s.abs() <= MAX_VORTICITY,
                &at("kind.per_s"),
                Num(per_s),
                &named(format!(
                    "a vorticity from -{MAX_VORTICITY} to {MAX_VORTICITY} 1/s, not 0 \
                     (positive turns anticlockwise)"
                )),
            )
        }
    }
}

/// A rectangle with area and a window of the period.
fn validate_area(
    (x0, y0, x1, y1): (f64, f64, f64, f64),
    (from, to): (f64, f64),
    period: f64,
    at: &dyn Fn(&str) -> String,
    named: &dyn Fn(String) -> String,
) -> Check {
    require(
        [x0, y0, x1, y1].iter().all(|v| v.is_finite()) && x0 < x1 && y0 < y1,
        &at("kind.rect"),
        format!("({}, {}, {}, {})", Num(x0), Num(y0), Num(x1), Num(y1)),
        &named("(x0, y0, x1, y1) in world metres with x0 < x1 and y0 < y1".into()),
    )?;
    require(
        (0.0..period).contains(&from) && to > from && to - from <= period,
        &at("kind.window_s"),
        format!("({}, {})", Num(from), Num(to)),
        &named(format!(
            "(from, to) in seconds with from in [0, {p}) and to after it, at most one period \
             ({p} s) later (a window ending past the period wraps round)",
            p = Num(period)
        )),
    )
}

/// Refuses an edit whose place is not on the painted maps (`width` x `height` m from the
/// origin): `Err((index, message))`.
pub fn check_edits_on_map(
    edits: &[Edit],
    (width, height): (f64, f64),
) -> Result<(), (usize, String)> {
    for (k, edit) in edits.iter().enumerate() {
        let (x0, y0, x1, y1) = edit.kind.rect();
        let on = |lo: f64, hi: f64, size: f64| lo >= 0.0 && hi <= size;
        if !(on(x0, x1, width) && on(y0, y1, height)) {
            return Err((
                k,
                format!(
                    "(edit `{}`) is at ({}, {}, {}, {}), not on the painted maps; expected a \
                     place inside (0, 0, {}, {}), the maps' size in world metres",
                    edit.name,
                    Num(x0),
                    Num(y0),
                    Num(x1),
                    Num(y1),
                    Num(width),
                    Num(height)
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> EditLimits {
        EditLimits {
            period_s: 20.0,
            rho_max: 0.35,
            max_speed: 1.8,
        }
    }

    fn parse(text: &str) -> Result<Vec<Edit>, String> {
        ron::from_str(text).map_err(|e| e.to_string())
    }

    /// The field and message an edit written as `text` is refused with.
    fn refused(text: &str) -> (String, String) {
        let edits = parse(text).unwrap();
        let bad = validate_edits(&edits, &limits()).unwrap_err();
        (bad.field, bad.message)
    }

    #[test]
    fn one_edit_of_each_kind_is_accepted() {
        let edits = parse(
            r#"[
            (name: "fountain", kind: Meet(at: (12, 40), time_s: 12)),
            (name: "square", kind: Density(rect: (0, 0, 8, 8), window_s: (8, 11), people_per_m2: 0.3)),
            (name: "bridge", kind: Flow(rect: (0, 0, 8, 8), window_s: (18, 24), velocity_m_s: (1, 0)), r: Some(0.1)),
            (name: "whirl", kind: Vorticity(rect: (0, 0, 8, 8), window_s: (2, 6), per_s: -0.5), q: Some(2)),
            (name: "turn", kind: FlowMap(rect: (0, 0, 8, 8), window_s: (2, 6), map: "turn.png", speed_m_s: 1.2)),
        ]"#,
        )
        .unwrap();
        validate_edits(&edits, &limits()).unwrap();
        assert_eq!(edits[0].kind.window(), (12.0, 12.0));
        assert!(matches!(edits[0].kind, EditKind::Meet { people: 2, .. }));
    }

    #[test]
    fn every_bad_edit_is_refused_naming_the_edit_and_the_field() {
        let cases = [
            (
                r#"[(name: "a", kind: Density(rect: (0, 0, 8, 8), window_s: (5, 30), people_per_m2: 0.3))]"#,
                "edits[0].kind.window_s",
                "at most one period",
            ),
            (
                r#"[(name: "a", kind: Density(rect: (0, 0, 8, 8), window_s: (5, 8), people_per_m2: 0.5))]"#,
                "edits[0].kind.people_per_m2",
                "optimize.rho_max",
            ),
            (
                r#"[(name: "a", kind: Density(rect: (8, 0, 0, 8), window_s: (5, 8), people_per_m2: 0.2))]"#,
                "edits[0].kind.rect",
                "x0 < x1",
            ),
            (
                r#"[(name: "a", kind: Meet(at: (1, 1), time_s: 20))]"#,
                "edits[0].kind.time_s",
                "a time in the period",
            ),
            (
                r#"[(name: "a", kind: Meet(at: (1, 1), time_s: 2, people: 40))]"#,
                "edits[0].kind.people",
                "from 1 to 12",
            ),
            (
                r#"[(name: "a", kind: Flow(rect: (0, 0, 8, 8), window_s: (5, 8), velocity_m_s: (3, 0)))]"#,
                "edits[0].kind.velocity_m_s",
                "match.max_speed",
            ),
            (
                r#"[(name: "a", kind: FlowMap(rect: (0, 0, 8, 8), window_s: (5, 8), map: "m.png", speed_m_s: 2.5))]"#,
                "edits[0].kind.speed_m_s",
                "match.max_speed",
            ),
            (
                r#"[(name: "a", kind: FlowMap(rect: (0, 0, 8, 8), window_s: (5, 8), map: "", speed_m_s: 1))]"#,
                "edits[0].kind.map",
                "flow-map PNG",
            ),
            (
                r#"[(name: "a", kind: Vorticity(rect: (0, 0, 8, 8), window_s: (5, 8), per_s: 0))]"#,
                "edits[0].kind.per_s",
                "not 0",
            ),
            (
                r#"[(name: "a", kind: Meet(at: (1, 1), time_s: 2)), (name: "a", kind: Meet(at: (2, 1), time_s: 2))]"#,
                "edits[1].name",
                "the name of edits[0] too",
            ),
            (
                r#"[(name: "a", kind: Meet(at: (1, 1), time_s: 2), r: Some(-1))]"#,
                "edits[0].r",
                "a positive weight",
            ),
        ];
        for (text, field, expected) in cases {
            let (f, message) = refused(text);
            assert_eq!(f, field, "{text}");
            assert!(message.contains(expected), "{text}: {message}");
            assert!(
                message.contains("edit `a`") || field == "edits[1].name",
                "{message}"
            );
        }
    }

    #[test]
    fn an_unknown_kind_or_an_edit_off_the_map_is_refused() {
        let err = parse(r#"[(name: "a", kind: Swirl(rect: (0, 0, 1, 1)))]"#).unwrap_err();
        assert!(err.contains("Swirl"), "{err}");
        let edits = parse(r#"[(name: "far", kind: Meet(at: (500, 1), time_s: 2))]"#).unwrap();
        let (k, message) = check_edits_on_map(&edits, (400.0, 400.0)).unwrap_err();
        assert_eq!(k, 0);
        assert!(message.contains("edit `far`") && message.contains("not on the painted maps"));
    }
}
