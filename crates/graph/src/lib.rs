//! Stage 2, graph: [`MergedMaps`] in, [`PatchGraph`] out (Crowd Art section 5, "From maps to
//! crowd patches").
//!
//! The world is cut into square patches of the configured side. Each patch gets the mean of its
//! pixels: walker and stander density (scaled so the scene holds the requested numbers of
//! characters), direction (where the direction weight asks for one) and obstacle coverage.
//! Empty and blocked patches are dropped; partial obstacles stay inside their patch as static
//! obstacles. Every border two kept patches share records the intervals where people can cross,
//! and petgraph's union-find gives the connected components.
//!
//! [`build_graph`] is the pure core; [`run`] is the I/O edge.

mod borders;
mod cells;
mod components;
mod density;

use crowd_core::config::{GraphSettings, People, PipelineFile};
use crowd_core::files::Header;
use crowd_core::patch_graph::{Dropped, World};
use crowd_core::{Error, Hash, Hasher, MergedMaps, Patch, PatchGraph, PatchId, Progress, Result};
use glam::DVec2;
use std::path::Path;

/// Everything of the pipeline that stage 2 reads, besides the merged maps.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GraphInputs {
    pub walkers: u64,
    pub standers: u64,
    pub people: People,
    pub patch_side_m: f64,
    pub radius_m: f64,
    /// No patch is asked for more characters per m2 than this (`optimize.rho_max`).
    pub rho_max: f64,
    pub settings: GraphSettings,
}

impl GraphInputs {
    /// `walkers` counted (no standers) over patches of `patch_side_m`, walkers of 0.3 m and
    /// the default `optimize.rho_max` and graph settings: the graph of a hand-made scene.
    pub fn counted(walkers: u64, patch_side_m: f64) -> GraphInputs {
        GraphInputs {
            walkers,
            standers: 0,
            people: People::Counted,
            patch_side_m,
            radius_m: 0.3,
            rho_max: crowd_core::config::OptimizeSettings::default().rho_max,
            settings: GraphSettings::default(),
        }
    }
}

/// Why painted maps and settings cannot make a patch graph.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraphProblem {
    #[error(
        "`walkers` is 0 but the density layers paint {pixels} pixels outside obstacles; \
         set `walkers` above 0 or remove the density layers"
    )]
    ZeroWalkers { pixels: u64 },
    #[error(
        "`walkers` is {walkers} but the density layers paint nothing outside obstacles and \
         empty patches; paint where they walk or set `walkers` to 0"
    )]
    NothingToWalkOn { walkers: u64 },
    #[error(
        "`standers` is {standers} but the static layers paint nothing outside obstacles and \
         empty patches; paint where they stand or set `standers` to 0"
    )]
    NowhereToStand { standers: u64 },
    #[error(
        "`{field}` is {requested} but at most {capacity} fit: the {painted} patches painted for \
         them hold at most rho_max = {rho_max} characters per m2{besides}; paint a larger area, \
         lower `{field}` or raise `optimize.rho_max`"
    )]
    OverCapacity {
        field: &'static str,
        requested: u64,
        capacity: u64,
        painted: usize,
        rho_max: f64,
        besides: &'static str,
    },
    #[error(
        "no walkable patch: of {cells} patches of {side_m} m, {empty} are empty (mean painted \
         density at most `graph.empty_below`) and {blocked} are blocked by obstacles"
    )]
    NoWalkablePatch {
        cells: u32,
        side_m: f64,
        empty: u32,
        blocked: u32,
    },
    #[error(
        "the maps are {width_m} x {height_m} m, smaller than one patch of {side_m} m; \
         use a smaller `patch_side_m`"
    )]
    MapsSmallerThanAPatch {
        width_m: f64,
        height_m: f64,
        side_m: f64,
    },
}

impl GraphProblem {
    /// The pipeline field a person should look at.
    pub fn field(&self) -> &'static str {
        match self {
            GraphProblem::ZeroWalkers { .. } | GraphProblem::NothingToWalkOn { .. } => "walkers",
            GraphProblem::NowhereToStand { .. } => "standers",
            GraphProblem::OverCapacity { field, .. } => field,
            GraphProblem::NoWalkablePatch { .. } => "scene.layers",
            GraphProblem::MapsSmallerThanAPatch { .. } => "patch_side_m",
        }
    }
}

/// Builds the patch graph. Deterministic whatever the thread count.
pub fn build_graph(
    maps: &MergedMaps,
    inputs: &GraphInputs,
    input_hash: Hash,
    progress: &dyn Progress,
) -> std::result::Result<PatchGraph, GraphProblem> {
    let mpp = maps.meters_per_pixel;
    let side_px = (inputs.patch_side_m / mpp).round() as u32;
    let cols = maps.width() / side_px;
    let rows = maps.height() / side_px;
    let size_m = DVec2::new(maps.width() as f64, maps.height() as f64) * mpp;
    if cols == 0 || rows == 0 {
        return Err(GraphProblem::MapsSmallerThanAPatch {
            width_m: size_m.x,
            height_m: size_m.y,
            side_m: inputs.patch_side_m,
        });
    }
    let world = World {
        cols,
        rows,
        patch_side_m: inputs.patch_side_m,
        meters_per_pixel: mpp,
        size_m,
    };
    let layout = cells::Layout::new(maps, side_px, cols, rows);
    progress.begin("graph", rows as u64 + 2);
    let stats = cells::measure(maps, &layout, progress);
    if inputs.people.is_counted() {
        check_walkers(maps, inputs)?;
    }

    let s = &inputs.settings;
    let mut empty = Vec::new();
    let mut blocked = Vec::new();
    let mut kept = Vec::new();
    for stat in &stats {
        if stat.coverage >= s.blocked_above {
            blocked.push(stat.cell);
        } else if stat.mean_walkers + stat.mean_standers <= s.empty_below {
            empty.push(stat.cell);
        } else {
            kept.push(stat);
        }
    }
    if kept.is_empty() {
        return Err(GraphProblem::NoWalkablePatch {
            cells: cols * rows,
            side_m: inputs.patch_side_m,
            empty: empty.len() as u32,
            blocked: blocked.len() as u32,
        });
    }
    let area = inputs.patch_side_m * inputs.patch_side_m;
    let (walker_density, stander_density) = match inputs.people {
        People::Counted => counted(&kept, inputs, area)?,
        People::PerSquareMetre { walkers, standers } => {
            // Standers first (they are fixed), walkers under what the standers leave.
            let s: Vec<f64> = kept
                .iter()
                .map(|c| (standers * c.mean_standers).min(inputs.rho_max))
                .collect();
            let w = kept
                .iter()
                .zip(&s)
                .map(|(c, s)| (walkers * c.mean_walkers).min((inputs.rho_max - s).max(0.0)))
                .collect();
            (w, s)
        }
    };
    let requested = |densities: &[f64]| (densities.iter().sum::<f64>() * area).round() as u64;
    let (walkers_requested, standers_requested) = match inputs.people {
        People::Counted => (inputs.walkers, inputs.standers),
        People::PerSquareMetre { .. } => (requested(&walker_density), requested(&stander_density)),
    };

    let mut patches: Vec<Patch> = kept
        .iter()
        .enumerate()
        .map(|(i, c)| Patch {
            id: PatchId(i as u32),
            cell: c.cell,
            walker_density: walker_density[i],
            stander_density: stander_density[i],
            direction: c.direction(s.direction_min_weight),
            obstacle_coverage: c.coverage,
            obstacles: c.obstacles.clone(),
            component: 0,
        })
        .collect();
    progress.advance(1);
    let min_opening = s.min_opening_m.unwrap_or(2.0 * inputs.radius_m);
    let mut borders = borders::find(maps, &layout, &patches, min_opening, inputs.radius_m);
    borders::close_cut_off_regions(maps, &layout, &patches, &mut borders, inputs.radius_m);
    let components = components::label(&mut patches, &borders, area);
    progress.advance(1);

    Ok(PatchGraph {
        header: Header::new(PatchGraph::STAGE, PatchGraph::VERSION, input_hash),
        world,
        walkers_requested,
        standers_requested,
        radius_m: inputs.radius_m,
        dropped: Dropped {
            empty,
            blocked,
            uncovered_strip_m: DVec2::new(
                (maps.width() - cols * side_px) as f64,
                (maps.height() - rows * side_px) as f64,
            ) * mpp,
        },
        components,
        patches,
        borders,
    })
}

/// Walker and stander densities per kept patch when the pipeline gives totals: the people are
/// poured in under the cap, standers first (they are fixed), walkers into what the standers
/// leave (see `density`).
fn counted(
    kept: &[&cells::CellStats],
    inputs: &GraphInputs,
    area: f64,
) -> std::result::Result<(Vec<f64>, Vec<f64>), GraphProblem> {
    // Sums in patch order, on one thread: the scale factor is bit-identical on every run.
    let painted_walkers: f64 = kept.iter().map(|c| c.mean_walkers).sum();
    let painted_standers: f64 = kept.iter().map(|c| c.mean_standers).sum();
    if inputs.walkers > 0 && painted_walkers <= 0.0 {
        return Err(GraphProblem::NothingToWalkOn {
            walkers: inputs.walkers,
        });
    }
    if inputs.standers > 0 && painted_standers <= 0.0 {
        return Err(GraphProblem::NowhereToStand {
            standers: inputs.standers,
        });
    }
    // People poured in under the cap: standers first (they are fixed), walkers into what the
    // standers leave (see `density`).
    let over = |field, requested: u64, weights: &[f64], besides| {
        let painted = weights.iter().filter(|&&w| w > 0.0).count();
        move |capacity: f64| GraphProblem::OverCapacity {
            field,
            requested,
            capacity: (capacity * area).floor() as u64,
            painted,
            rho_max: inputs.rho_max,
            besides,
        }
    };
    let stander_weights: Vec<f64> = kept.iter().map(|c| c.mean_standers).collect();
    let stander_caps = vec![inputs.rho_max; kept.len()];
    let stander_density = density::fill_under_caps(
        &stander_weights,
        &stander_caps,
        inputs.standers as f64 / area,
    )
    .map_err(over("standers", inputs.standers, &stander_weights, ""))?;
    let walker_weights: Vec<f64> = kept.iter().map(|c| c.mean_walkers).collect();
    let walker_caps: Vec<f64> = stander_density
        .iter()
        .map(|s| (inputs.rho_max - s).max(0.0))
        .collect();
    let walker_density =
        density::fill_under_caps(&walker_weights, &walker_caps, inputs.walkers as f64 / area)
            .map_err(over(
                "walkers",
                inputs.walkers,
                &walker_weights,
                " with the standers",
            ))?;
    Ok((walker_density, stander_density))
}

fn check_walkers(maps: &MergedMaps, inputs: &GraphInputs) -> std::result::Result<(), GraphProblem> {
    if inputs.walkers == 0 {
        let pixels = maps.walkers.as_slice().iter().filter(|&&v| v > 0.0).count() as u64;
        if pixels > 0 {
            return Err(GraphProblem::ZeroWalkers { pixels });
        }
    }
    Ok(())
}

/// What stage 2 reads from a pipeline.
pub fn inputs(pipeline: &PipelineFile) -> GraphInputs {
    let p = &pipeline.pipeline;
    GraphInputs {
        walkers: p.walkers,
        standers: p.standers,
        people: p.people,
        patch_side_m: p.patch_side_m,
        radius_m: p.radius_m,
        rho_max: p.optimize.rho_max,
        settings: p.graph.clone(),
    }
}

/// The hash of stage 2's inputs: the merge file (its bytes' hash) and the graph settings.
pub fn input_hash(merge_file: &Hash, inputs: &GraphInputs) -> Hash {
    Hasher::new(PatchGraph::STAGE, PatchGraph::VERSION)
        .file_hash("merge file", merge_file)
        .value("inputs", inputs)
        .finish()
}

/// Builds the graph of a pipeline from stage 1's maps and the hash of its file's bytes
/// (`merge` names it in messages). Problems of the scene point at the pipeline setting to
/// change.
pub fn build(
    pipeline: &PipelineFile,
    merge: &Path,
    merge_file: &Hash,
    maps: &MergedMaps,
    progress: &dyn Progress,
) -> Result<PatchGraph> {
    if (maps.meters_per_pixel - pipeline.pipeline.scene.meters_per_pixel).abs() > 1e-12 {
        return Err(Error::stage_file(
            merge,
            "was merged at another `scene.meters_per_pixel` than the pipeline's: merge again",
        ));
    }
    let inputs = inputs(pipeline);
    let hash = input_hash(merge_file, &inputs);
    build_graph(maps, &inputs, hash, progress)
        .map_err(|problem| pipeline.scene_error(problem.field(), problem.to_string()))
}

#[cfg(test)]
mod tests;
