//! What a build could not give its painting, said plainly: on stderr after `crowd build`, in
//! `report.md` with a picture of where, and as a failure under `--deny-warnings` (for build
//! systems that must not ship a crowd that differs from what was painted).
//!
//! The build still writes a collision-free result; a warning names the patches and says why.
//! A defect the pipeline cannot clear (a patch stage 5 leaves colliding) is an error of the
//! stage instead, never a warning.

use crate::check::CHECK_FILE;
use crate::stages::{COLLIDED_FILE, EDITED_FILE, GRAPH_FILE};
use anyhow::{Result, bail};
use crowd_core::PatchGraph;
use crowd_core::config::PipelineFile;
use crowd_core::trajectories::{CollisionSummary, EditSummary, MotionSummary};
use std::path::Path;

/// One thing the build could not meet.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// The patches it is about (none: the whole build).
    pub patches: Vec<u32>,
    pub text: String,
}

/// The warnings of the build in `dir`, from its stage files and `check.ron` (those it has).
pub fn gather(dir: &Path) -> Result<Vec<Warning>> {
    let graph_path = dir.join(GRAPH_FILE);
    let Ok(graph) = PatchGraph::load_shared(&graph_path) else {
        return Ok(Vec::new());
    };
    let mut out = pockets(&graph);
    let collided = dir.join(COLLIDED_FILE);
    if collided.exists() {
        let file: crowd_core::trajectories::TrajectoriesFile =
            crowd_core::files::read_ron(&collided)?;
        out.extend(shortfall(&graph, &file.summary));
        if let Some(summary) = &file.collisions {
            out.extend(hurried(&graph, summary));
        }
    }
    let edited = dir.join(EDITED_FILE);
    if edited.exists() {
        let file: crowd_core::trajectories::TrajectoriesFile =
            crowd_core::files::read_ron(&edited)?;
        out.extend(edits(file.edits.as_deref().unwrap_or_default()));
    }
    let check = dir.join(CHECK_FILE);
    if check.exists() {
        let figures: crowd_check::CheckReport = crowd_core::files::read_ron(&check)?;
        out.extend(shipped(&figures));
    }
    Ok(out)
}

/// Stage 7's edits that could not do what they asked.
fn edits(edits: &[EditSummary]) -> Vec<Warning> {
    edits
        .iter()
        .filter_map(|e| {
            e.warning.as_ref().map(|w| Warning {
                patches: e.patches.clone(),
                text: format!("edit \"{}\": {w}", e.name),
            })
        })
        .collect()
}

/// Where patch `p` lies, for a person: its world rectangle in metres.
pub(crate) fn place(graph: &PatchGraph, p: u32) -> String {
    let side = graph.world.patch_side_m;
    let cell = graph.patches[p as usize].cell;
    let (x, y) = (f64::from(cell.col) * side, f64::from(cell.row) * side);
    format!(
        "patch {p} (x {x:.0}-{:.0} m, y {y:.0}-{:.0} m)",
        x + side,
        y + side
    )
}

/// Painted walkers in a walled-in pocket: no open border, so no one can walk in or out.
fn pockets(graph: &PatchGraph) -> Vec<Warning> {
    let open = open_components(graph);
    graph
        .components
        .iter()
        .filter(|c| !open[c.id as usize] && c.walkers >= 0.5)
        .map(|c| {
            let patches: Vec<u32> = graph
                .patches
                .iter()
                .filter(|p| p.component == c.id)
                .map(|p| p.id.0)
                .collect();
            Warning {
                text: format!(
                    "{} is walled in: painted for {:.1} walkers, but no border of it is open, so \
                     no one can walk in or out; it has no walkers (open a gap of at least a \
                     walker's width in its walls, or paint it as standing)",
                    place(graph, patches[0]),
                    c.walkers
                ),
                patches,
            }
        })
        .collect()
}

/// Walkers painted in components with an open border: those someone can walk in and out of.
fn reachable_walkers(graph: &PatchGraph) -> f64 {
    let open = open_components(graph);
    (graph.components.iter())
        .filter(|c| open[c.id as usize])
        .map(|c| c.walkers)
        .sum()
}

/// Which components have an open border.
fn open_components(graph: &PatchGraph) -> Vec<bool> {
    let mut open = vec![false; graph.components.len()];
    for b in graph.borders.iter().filter(|b| !b.open.is_empty()) {
        for p in [b.a, b.b] {
            open[graph.patches[p.0 as usize].component as usize] = true;
        }
    }
    open
}

/// The settings that ask for walkers and standers: the build folder does not say which of the
/// two ways `people` was given, so a warning read from it names both.
const WALKERS: &str = "`walkers`, or `people.walkers` per m2";
const STANDERS: &str = "`standers`, or `people.standers` per m2";

/// A build placing fewer walkers or standers than asked, or more walkers, by more than rounding
/// (a tenth, and at least one character): what was asked, what was placed, and the likely
/// cause.
fn shortfall(graph: &PatchGraph, summary: &MotionSummary) -> Vec<Warning> {
    let off = |x: f64, asked: f64| x > (0.1 * asked).max(1.0);
    let short = |asked: f64, placed: f64| off(asked - placed, asked);
    let mut out = Vec::new();
    let asked = graph.walkers_requested as f64;
    if off(summary.walkers_measured - asked, asked) {
        out.push(Warning {
            patches: Vec::new(),
            text: format!(
                "{:.0} walkers placed of {asked:.0} asked ({WALKERS}): the paint is so sparse \
                 ({}) that stage 3's whole walkers, each crossing a patch in seconds, and those \
                 it sends to walk the painted directions, come out more than asked; raise it, \
                 paint them into a smaller area, or weaken the direction layers where little \
                 is painted",
                summary.walkers_measured,
                density_figures(graph)
            ),
        });
    }
    if short(asked, summary.walkers_measured) {
        let walled = asked - reachable_walkers(graph);
        let why = if walled > (0.1 * asked).max(1.0) {
            format!(
                "{walled:.0} of them are painted where no border is open (see the walled-in warnings)"
            )
        } else {
            format!(
                "the paint is so sparse ({}) that stage 3's whole walkers, each crossing a \
                 patch in seconds, come out fewer than asked; raise it, paint them \
                 into a smaller area or lower `scene.meters_per_pixel`",
                density_figures(graph)
            )
        };
        out.push(Warning {
            patches: Vec::new(),
            text: format!(
                "{:.0} walkers placed of {asked:.0} asked ({WALKERS}): {why}",
                summary.walkers_measured
            ),
        });
    }
    let asked = graph.standers_requested as f64;
    if short(asked, summary.standers as f64) {
        out.push(Warning {
            patches: Vec::new(),
            text: format!(
                "{} standers placed of {asked:.0} asked ({STANDERS}): their patches have no \
                 room for more with clearance (rho_max caps each patch), or the stander layer \
                 is painted where walls stand",
                summary.standers
            ),
        });
    }
    out
}

/// The painted walker density, mean and largest, per m2.
fn density_figures(graph: &PatchGraph) -> String {
    let n = graph.patches.len().max(1) as f64;
    let mean = graph.patches.iter().map(|p| p.walker_density).sum::<f64>() / n;
    let max = (graph.patches.iter())
        .map(|p| p.walker_density)
        .fold(0.0, f64::max);
    format!("{mean:.4} walkers per m2 on average, {max:.4} at most")
}

/// The error of a build whose stage 3 placed no walker although walkers were asked for: an
/// empty crowd is never written. Says why: every painted walker walled in, or paint so sparse
/// that one walker crossing a patch is already far more than it asks.
pub fn no_walker(graph: &PatchGraph, pipeline: &PipelineFile) -> Result<()> {
    let asked = graph.walkers_requested;
    let p = &pipeline.pipeline;
    if asked == 0 {
        if let crowd_core::config::People::PerSquareMetre { walkers, .. } = p.people
            && walkers > 0.0
        {
            bail!(
                "{}: stage 3 placed no walker: `people.walkers` is {walkers} per m2 where the \
                 `Density` layer is painted full, and the painting asks for fewer than one \
                 walker in all ({}); paint brighter or raise `people.walkers`; no file was \
                 written",
                pipeline.path.display(),
                density_figures(graph)
            );
        }
        return Ok(());
    }
    if reachable_walkers(graph) < 0.5 {
        bail!(
            "{}: stage 3 placed no walker: the {asked} walkers asked (`walkers`) are all painted \
             in parts walled in on every side, which no one can walk in or out of; open a gap \
             of at least a walker's width, or paint them as standing; no file was written",
            pipeline.path.display()
        );
    }
    // A walker crossing a patch at comfort speed stays side / speed seconds of the period.
    let side = graph.world.patch_side_m;
    let one = 1.0 / (p.matching.comfort_speed * p.period_s * side);
    let size = graph.world.size_m;
    let field = match p.people {
        crowd_core::config::People::Counted => "walkers",
        crowd_core::config::People::PerSquareMetre { .. } => "people.walkers",
    };
    bail!(
        "{}: stage 3 placed no walker: {asked} walkers (`{field}`) over {} patches of {side} m \
         ({}) is sparser than one walker crossing a patch once a period makes it (about {one:.4} \
         per m2 over the {} s period), so the nearest crowd is an empty one; raise `{field}`, \
         paint them into a smaller area, or lower `scene.meters_per_pixel` (the maps cover \
         {:.0} x {:.0} m); no file was written",
        pipeline.path.display(),
        graph.patches.len(),
        density_figures(graph),
        p.period_s,
        size.x,
        size.y
    )
}

/// Patches that stage 5 cleared only by letting a walker hurry past `match.max_speed`.
fn hurried(graph: &PatchGraph, summary: &CollisionSummary) -> Vec<Warning> {
    summary
        .hurried
        .iter()
        .map(|h| Warning {
            patches: vec![h.patch],
            text: format!(
                "{}: walker {} runs at {:.2} m/s at t = {:.2} s, faster than match.max_speed \
                 allows: at walking pace stage 5 found no way to keep it clear of the others \
                 there; the painting asks for more walkers, or more crossing flows, than the \
                 patch has room and time for",
                place(graph, h.patch),
                h.walker,
                h.speed_m_s,
                h.t_s
            ),
        })
        .collect()
}

/// Guarantees `crowd check` found broken in what ships.
pub(crate) fn shipped(figures: &crowd_check::CheckReport) -> Vec<Warning> {
    let mut out = Vec::new();
    for p in [&figures.library, &figures.gltf].into_iter().flatten() {
        let mut say = |text: String| {
            out.push(Warning {
                patches: Vec::new(),
                text: format!("{}: {text}", p.file),
            })
        };
        if let Some(how) = &p.unlike_manifest {
            say(how.clone());
        }
        if p.collisions > 0 {
            say(format!(
                "{} pairs come closer than two radii (smallest clearance {:.4} m)",
                p.collisions, p.min_clearance_m
            ));
        }
        if p.share_above_limit > 0.0 {
            say(format!(
                "walkers are faster than {:.2} m/s for {:.4} % of walking time (fastest {:.2} \
                 m/s)",
                p.speed_limit_m_s,
                100.0 * p.share_above_limit,
                p.max_speed_m_s
            ));
        }
        if p.open_loops > 0 {
            say(format!(
                "{} of {} loops do not close (a character jumps at the loop seam)",
                p.open_loops, p.loops
            ));
        }
        if let (Some(turn), Some(limit)) = (p.max_turn_rate_rad_s, p.turn_rate_limit_rad_s)
            && turn > limit
        {
            say(format!(
                "characters turn at up to {:.1} degrees a second, above {:.1} \
                 (`export.turn_rate_deg_s` and the keys' rounding)",
                turn.to_degrees(),
                limit.to_degrees()
            ));
        }
        if let Some(s) = p.sampled.as_ref().filter(|s| s.jumps > 0) {
            say(format!(
                "played by crowd-runtime every {} s, characters jump {} times",
                s.step_s, s.jumps
            ));
        }
    }
    out
}

/// Draws the world's patch graph with the patches `warnings` name in red, into a PNG at `out`.
pub fn draw(dir: &Path, warnings: &[Warning], out: &Path) -> Result<&'static str> {
    let graph = PatchGraph::load_shared(&dir.join(GRAPH_FILE))?;
    let marked: Vec<u32> = warnings.iter().flat_map(|w| w.patches.clone()).collect();
    crowd_render::save_png(&crowd_render::render_marked(&graph, &marked), out)?;
    Ok(crowd_render::MARKED_LEGEND)
}
