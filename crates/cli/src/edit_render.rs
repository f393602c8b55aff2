//! `crowd render edited.ron --edit NAME`: one edit of stage 7 before and after, as a person
//! would look at it. Each patch the edit covers is drawn from above twice, as stage 6 left it
//! (left) and as stage 7 ships it (right): every walker's path over the edit's window and two
//! seconds either side, the walkers as discs at the window's middle (a meeting's instant), the
//! edit's rectangle outlined or its meeting point ringed.

use crate::stages::{GRAPH_FILE, SMOOTHED_FILE};
use anyhow::{Result, bail};
use crowd_core::PatchGraph;
use crowd_core::config::{Edit, EditKind, PipelineFile};
use crowd_core::trajectories::{PatchMotion, TrajectoriesFile, position_at};
use crowd_render::line_colour;
use crowd_render::plot::{Outline, TopView, side_by_side, top_view};
use glam::DVec2;
use image::{Rgb, RgbImage};
use std::path::Path;

/// What the picture shows, for `crowd render`'s message.
pub const EDIT_LEGEND: &str = "each patch the edit covers, as stage 6 left it (left) and as \
     stage 7 ships it (right), from above: every walker's path from 2 s before the edit's \
     window to 2 s after (one colour per walker), discs = the walkers at the window's middle \
     (a meeting's instant), black outline = the edit's rectangle, black ring = its meeting \
     point, dark = obstacles";

/// Seconds drawn either side of the window.
const AROUND_S: f64 = 2.0;
/// Pixels per metre.
const SCALE: f64 = 40.0;

/// The picture of the edit called `name`, from `edited` (stage 7's file) and the files beside
/// it; the edit itself is read from `pipeline`.
pub fn render_edit(edited: &Path, name: &str, pipeline: &Path) -> Result<RgbImage> {
    let pipeline = PipelineFile::load(pipeline)?;
    let Some(edit) = pipeline.pipeline.edits.iter().find(|e| e.name == name) else {
        let names: Vec<&str> = pipeline
            .pipeline
            .edits
            .iter()
            .map(|e| e.name.as_str())
            .collect();
        bail!(
            "{}: no edit named `{name}`; its edits are {names:?}",
            pipeline.path.display()
        );
    };
    let graph = PatchGraph::load(&edited.with_file_name(GRAPH_FILE))?;
    let (file, after) =
        TrajectoriesFile::load_stage(edited, crowd_moments::STAGE, crowd_moments::VERSION)?;
    let (_, before) = TrajectoriesFile::load_stage(
        &edited.with_file_name(SMOOTHED_FILE),
        crowd_smooth::STAGE,
        crowd_smooth::VERSION,
    )?;
    let Some(summary) = file.edits.iter().flatten().find(|e| e.name == name) else {
        bail!(
            "{}: holds no edit named `{name}` (build again after changing the edits)",
            edited.display()
        );
    };
    if summary.patches.is_empty() {
        bail!("{}: the edit `{name}` covers no patch", edited.display());
    }
    let panels: Vec<RgbImage> = summary
        .patches
        .iter()
        .flat_map(|&p| {
            let p = p as usize;
            [&before[p], &after[p]].map(|m| patch_view(&graph, p, m, edit, file.period_s))
        })
        .collect();
    Ok(side_by_side(&panels, 12))
}

/// Patch `p` from above, walking `motion` around the edit's window.
fn patch_view(
    graph: &PatchGraph,
    p: usize,
    motion: &PatchMotion,
    edit: &Edit,
    period: f64,
) -> RgbImage {
    let side = graph.world.patch_side_m;
    let origin = graph.world_from_patch(graph.patches[p].cell);
    let (w0, w1) = edit.kind.window();
    let middle = (w0 + w1) / 2.0;
    let mut paths = Vec::new();
    let mut discs = Vec::new();
    for (j, tr) in motion.trajectories.iter().enumerate() {
        let (a, b) = (tr.points[0].t, tr.points[tr.points.len() - 1].t);
        let colour = line_colour(j);
        for m in -1..=2 {
            let shift = m as f64 * period;
            let (from, to) = (
                (w0 - AROUND_S - shift).max(a),
                (w1 + AROUND_S - shift).min(b),
            );
            if from >= to {
                continue;
            }
            let steps = ((to - from) / 0.05).ceil() as usize;
            let path: Vec<DVec2> = (0..=steps)
                .map(|k| position_at(&tr.points, from + (to - from) * k as f64 / steps as f64))
                .collect();
            paths.push((path, lighter(colour)));
            let at = middle - shift;
            if (a..=b).contains(&at) {
                discs.push((position_at(&tr.points, at), graph.radius_m, colour, true));
            }
        }
    }
    for &s in &motion.standers {
        discs.push((s, graph.radius_m, Rgb([200, 120, 160]), true));
    }
    let ink = Rgb([20, 20, 20]);
    let mut outlines = Vec::new();
    match edit.kind {
        EditKind::Meet { at, .. } => {
            discs.push((DVec2::new(at.0, at.1) - origin, 0.15, ink, false));
        }
        _ => {
            let (x0, y0, x1, y1) = edit.kind.rect();
            outlines.push(Outline {
                min: (DVec2::new(x0, y0) - origin).max(DVec2::ZERO),
                max: (DVec2::new(x1, y1) - origin).min(DVec2::splat(side)),
                colour: ink,
            });
        }
    }
    let obstacles: Vec<(DVec2, DVec2)> = graph.patches[p]
        .obstacles
        .iter()
        .map(|o| (o.min, o.max))
        .collect();
    top_view(
        &TopView {
            min: DVec2::ZERO,
            max: DVec2::splat(side),
            obstacles: &obstacles,
            outlines: &outlines,
            paths: &paths,
            discs: &discs,
        },
        SCALE,
    )
}

fn lighter(c: Rgb<u8>) -> Rgb<u8> {
    let mix = |v: u8| ((v as u16 + 255) / 2) as u8;
    Rgb([mix(c.0[0]), mix(c.0[1]), mix(c.0[2])])
}
