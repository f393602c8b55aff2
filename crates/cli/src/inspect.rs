//! `crowd inspect` and `crowd render`: any stage file, told apart by its header.

use crate::stages::{EXPORT_FILE, GRAPH_FILE, PATTERNS_FILE};
use anyhow::{Result, bail};
use crowd_core::files;
use crowd_core::maps::MergeFile;
use crowd_core::patch_graph::BorderAxis;
use crowd_core::patterns::{Crossing, Patterns};
use crowd_core::trajectories::TrajectoriesFile;
use crowd_core::{MergedMaps, PatchGraph};
use std::fmt::Write;
use std::path::Path;

/// A readable summary of a stage file. A build folder, or the library or glTF world that stage
/// 8 wrote, is summed up through the manifest beside them (`export.ron`), which verifies them.
pub fn inspect(path: &Path) -> Result<String> {
    if let Some(manifest) = manifest_for(path)? {
        return inspect_export(&manifest);
    }
    let header = files::read_header(path)?;
    match header.stage.as_str() {
        MergeFile::STAGE => {
            let (file, maps) = MergeFile::load(path)?;
            Ok(inspect_merge(&file, &maps))
        }
        PatchGraph::STAGE => Ok(inspect_graph(&PatchGraph::load(path)?)),
        Patterns::STAGE => {
            let (patterns, crossings) = Patterns::load(path)?;
            Ok(inspect_patterns(&patterns, &crossings))
        }
        stage @ (TrajectoriesFile::STAGE
        | crowd_collide::STAGE
        | crowd_smooth::STAGE
        | crowd_moments::STAGE) => Ok(inspect_trajectories(
            &TrajectoriesFile::load_stage(path, stage, version_of(stage))?.0,
        )),
        crowd_export::STAGE => inspect_export(path),
        other => bail!(
            "{}: `crowd inspect` does not know `{other}` files",
            path.display()
        ),
    }
}

/// The manifest to inspect for `path` when it is a build folder or a product of stage 8 (the
/// binary files a user is most likely to name): `export.ron` in the folder or beside the file.
/// `None` for anything else; an error when the manifest is not there.
fn manifest_for(path: &Path) -> Result<Option<std::path::PathBuf>> {
    let (manifest, what) = if path.is_dir() {
        (path.join(EXPORT_FILE), "a build folder")
    } else if [crowd_export::LIBRARY_FILE, crowd_export::GLB_FILE]
        .iter()
        .any(|name| path.file_name().is_some_and(|f| f == *name))
    {
        (path.with_file_name(EXPORT_FILE), "a product of stage 8")
    } else {
        return Ok(None);
    };
    if !manifest.exists() {
        bail!(
            "{}: {what}, read through the manifest stage 8 writes, but {} is not there (build \
             again, or name a stage file)",
            path.display(),
            manifest.display()
        );
    }
    Ok(Some(manifest))
}

/// The format version this build reads of the files of `stage` (the header's stage name): the
/// stage's `VERSION`, never the version the file claims, so an old file is refused. Called
/// with the stage names of the table only.
fn version_of(stage: &str) -> u32 {
    crate::stages::STAGES
        .iter()
        .find(|s| s.kind == stage)
        .expect("a stage of the table")
        .version
}

/// Stage 8's manifest, its library and glTF world verified against it (size and hash), and
/// the library loaded and checked as crowd-runtime loads it.
fn inspect_export(path: &Path) -> Result<String> {
    let file: crowd_export::ExportFile = files::read_ron(path)?;
    files::expect_stage(
        path,
        &file.header,
        crowd_export::STAGE,
        crowd_export::VERSION,
    )?;
    let library_path = path.with_file_name(&file.library);
    let opened = std::fs::File::open(&library_path)
        .map_err(|e| anyhow::anyhow!("{}: {e}", library_path.display()))?;
    // What the runtime says of a damaged library first (it names the section), then whether
    // both files are the ones the manifest names.
    let lib = crowd_runtime::Library::read_from(opened)
        .map_err(|e| anyhow::anyhow!("{}: {e}", library_path.display()))?;
    for (name, differs) in [
        (&file.library, file.library_differs(path)),
        (&file.gltf, file.gltf_differs(path)),
    ] {
        if let Some(how) = differs {
            bail!("{}: {how}", path.with_file_name(name).display());
        }
    }
    let mut s = String::new();
    let mb = |b: u64| b as f64 / 1e6;
    let _ = writeln!(
        s,
        "stage 8 (export), built from {}",
        file.header.input_hash.short()
    );
    let _ = writeln!(
        s,
        "{}: {:.1} MB, loads and checks: {} walkers on {} loops, {} standers, {} patches, {} points",
        file.library,
        mb(file.library_bytes),
        lib.walkers(),
        lib.characters.len(),
        lib.standers.len(),
        lib.patches.len(),
        lib.points.len()
    );
    let _ = writeln!(
        s,
        "  quantised to within {:.3} mm and {:.3} ms; period {} s",
        file.position_error_m * 1e3,
        file.time_error_s * 1e3,
        lib.period_s()
    );
    let region = match file.gltf_region {
        Some((x0, y0, x1, y1)) => format!("the characters in x {x0}-{x1} m, y {y0}-{y1} m"),
        None => "the whole world".to_string(),
    };
    let _ = writeln!(s, "{}: {:.1} MB, {region}", file.gltf, mb(file.gltf_bytes));
    Ok(s)
}

/// Renders a stage file to `out` and returns the legend of the picture. Files of later
/// stages read the earlier stage files beside them (`graph.ron`, `patterns.ron`).
pub fn render(path: &Path, out: &Path, patch: Option<u32>) -> Result<&'static str> {
    let header = files::read_header(path)?;
    let beside = |name: &str| path.with_file_name(name);
    let (image, legend) = match header.stage.as_str() {
        Patterns::STAGE => {
            let graph = PatchGraph::load_shared(&beside(GRAPH_FILE))?;
            let (patterns, _) = Patterns::load(path)?;
            (
                crowd_render::render_patterns(&graph, &patterns),
                crowd_render::PATTERNS_LEGEND,
            )
        }
        stage @ (TrajectoriesFile::STAGE
        | crowd_collide::STAGE
        | crowd_smooth::STAGE
        | crowd_moments::STAGE) => {
            let graph = PatchGraph::load_shared(&beside(GRAPH_FILE))?;
            let (patterns, crossings) = Patterns::load_for(&beside(PATTERNS_FILE), &graph)?;
            let patches = graph.patches.len();
            if let Some(p) = patch
                && p as usize >= patches
                && patches > 0
            {
                bail!(
                    "--patch {p}: {} holds patches 0 to {}",
                    path.display(),
                    patches - 1
                );
            }
            let choose = |index: &crowd_core::trajectories::MotionIndex| {
                let busiest = (0..index.patches())
                    .max_by_key(|&p| (index.trajectories(p), std::cmp::Reverse(p)));
                patch.map(|p| p as usize).or(busiest)
            };
            let (_, chosen) =
                TrajectoriesFile::load_patch(path, stage, version_of(stage), patches, choose)?;
            let Some((p, motion)) = chosen else {
                bail!("{}: holds no patch", path.display());
            };
            let image =
                crowd_render::render_patch(&graph, &crossings, &motion, p, patterns.period_s);
            (image, crowd_render::PATCH_LEGEND)
        }
        MergeFile::STAGE => {
            let (_, maps) = MergeFile::load(path)?;
            (crowd_render::render_maps(&maps), crowd_render::MAPS_LEGEND)
        }
        PatchGraph::STAGE => (
            crowd_render::render_graph(&*PatchGraph::load_shared(path)?),
            crowd_render::GRAPH_LEGEND,
        ),
        other => bail!(
            "{}: `crowd render` does not know `{other}` files",
            path.display()
        ),
    };
    crowd_render::save_png(&image, out)?;
    Ok(legend)
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64, f64) {
    let (mut lo, mut hi, mut sum, mut n) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0usize);
    for v in values {
        lo = lo.min(v);
        hi = hi.max(v);
        sum += v;
        n += 1;
    }
    if n == 0 {
        (0.0, 0.0, 0.0)
    } else {
        (lo, sum / n as f64, hi)
    }
}

fn inspect_merge(file: &MergeFile, maps: &MergedMaps) -> String {
    let mut s = String::new();
    let h = &file.header;
    let _ = writeln!(s, "stage file: {} (format version {})", h.stage, h.version);
    let _ = writeln!(s, "built from: {}", h.input_hash);
    let _ = writeln!(
        s,
        "maps:       {} x {} px at {} m/px = {} x {} m",
        file.width,
        file.height,
        file.meters_per_pixel,
        file.width as f64 * file.meters_per_pixel,
        file.height as f64 * file.meters_per_pixel
    );
    let _ = writeln!(s, "layers:");
    for l in &file.layers {
        let _ = writeln!(
            s,
            "  {:<10} weight {:<5} {:<18} {}  ({})",
            l.kind.name(),
            l.weight,
            l.format,
            l.path,
            l.hash.short()
        );
    }
    let n = (file.width as u64 * file.height as u64).max(1);
    let pct = |k: u64| 100.0 * k as f64 / n as f64;
    let m = &file.summary;
    let (_, wmean, wmax) = range(maps.walkers.as_slice().iter().map(|&v| v as f64));
    let (_, smean, smax) = range(maps.standers.as_slice().iter().map(|&v| v as f64));
    let _ = writeln!(
        s,
        "walker density:  {:>8} px painted ({:.1} %), mean {wmean:.4}, max {wmax:.4}",
        m.walker_pixels,
        pct(m.walker_pixels)
    );
    let _ = writeln!(
        s,
        "stander density: {:>8} px painted ({:.1} %), mean {smean:.4}, max {smax:.4}",
        m.stander_pixels,
        pct(m.stander_pixels)
    );
    let _ = writeln!(
        s,
        "direction:       {:>8} px painted ({:.1} %)",
        m.directed_pixels,
        pct(m.directed_pixels)
    );
    let _ = writeln!(
        s,
        "obstacles:       {:>8} px blocked ({:.1} %)",
        m.blocked_pixels,
        pct(m.blocked_pixels)
    );
    let _ = writeln!(
        s,
        "grids:      {} ({} bytes, {})",
        file.grids.file,
        file.grids.bytes,
        file.grids.hash.short()
    );
    s
}

fn inspect_graph(g: &PatchGraph) -> String {
    let mut s = String::new();
    let h = &g.header;
    let area = g.patch_area();
    let _ = writeln!(s, "stage file: {} (format version {})", h.stage, h.version);
    let _ = writeln!(s, "built from: {}", h.input_hash);
    let w = &g.world;
    let _ = writeln!(
        s,
        "world:      {} x {} cells of {} m ({} x {} m of maps)",
        w.cols, w.rows, w.patch_side_m, w.size_m.x, w.size_m.y
    );
    if w.size_m.x > (w.cols as f64) * w.patch_side_m
        || w.size_m.y > (w.rows as f64) * w.patch_side_m
    {
        let strip = g.dropped.uncovered_strip_m;
        let _ = writeln!(
            s,
            "            {} m (east) and {} m (north) of the maps are not a whole patch and are left out",
            strip.x, strip.y
        );
    }
    let _ = writeln!(
        s,
        "patches:    {} kept, {} empty and {} blocked dropped",
        g.patches.len(),
        g.dropped.empty.len(),
        g.dropped.blocked.len()
    );
    let walkers: f64 = g.patches.iter().map(|p| p.walker_density * area).sum();
    let standers: f64 = g.patches.iter().map(|p| p.stander_density * area).sum();
    let (lo, mean, hi) = range(g.patches.iter().map(|p| p.walker_density));
    let _ = writeln!(
        s,
        "walkers:    {} requested, {walkers:.2} in patches; density {lo:.4} / {mean:.4} / {hi:.4} per m2 (min / mean / max)",
        g.walkers_requested
    );
    let (_, smean, shi) = range(g.patches.iter().map(|p| p.stander_density));
    let _ = writeln!(
        s,
        "standers:   {} requested, {standers:.2} in patches; density mean {smean:.4}, max {shi:.4} per m2",
        g.standers_requested
    );
    let directed = g.patches.iter().filter(|p| p.direction.is_some()).count();
    let _ = writeln!(s, "directions: {directed} patches request one");
    let partial = g.patches.iter().filter(|p| !p.obstacles.is_empty()).count();
    let rects: usize = g.patches.iter().map(|p| p.obstacles.len()).sum();
    let _ = writeln!(
        s,
        "obstacles:  {partial} patches hold partial obstacles ({rects} rectangles)"
    );
    let open = g
        .borders
        .iter()
        .filter(|b| b.open.len() == 1 && (b.open[0].len() - w.patch_side_m).abs() < 1e-9)
        .count();
    let closed = g.borders.iter().filter(|b| b.open.is_empty()).count();
    let vertical = g
        .borders
        .iter()
        .filter(|b| b.axis == BorderAxis::Vertical)
        .count();
    let _ = writeln!(
        s,
        "borders:    {} shared ({vertical} north-south, {} west-east): {open} fully open, {} partly closed, {closed} closed",
        g.borders.len(),
        g.borders.len() - vertical,
        g.borders.len() - open - closed
    );
    let _ = writeln!(s, "components: {}", g.components.len());
    let mut by_size: Vec<_> = g.components.iter().collect();
    by_size.sort_by(|a, b| b.patches.cmp(&a.patches).then(a.id.cmp(&b.id)));
    for c in by_size.iter().take(5) {
        let _ = writeln!(
            s,
            "  #{:<5} {:>6} patches, {:>10.1} walkers, {:>8.1} standers",
            c.id, c.patches, c.walkers, c.standers
        );
    }
    if by_size.len() > 5 {
        let _ = writeln!(s, "  ... and {} smaller", by_size.len() - 5);
    }
    s
}

fn inspect_patterns(p: &Patterns, crossings: &[Crossing]) -> String {
    let mut s = String::new();
    let h = &p.header;
    let _ = writeln!(s, "stage file: {} (format version {})", h.stage, h.version);
    let _ = writeln!(s, "built from: {}", h.input_hash);
    let e = &p.error;
    let _ = writeln!(
        s,
        "error:      E = {:.4} (E_rho {:.4}, E_d {:.4}); rho_max {}",
        e.e, e.e_rho, e.e_d, p.rho_max
    );
    let _ = writeln!(
        s,
        "iterations: {} ({})",
        p.iterations,
        if p.converged {
            "converged: no better E in the last steps"
        } else {
            "stopped at the cap"
        }
    );
    let r = &p.regression;
    let _ = writeln!(
        s,
        "regression: density = {:.5} x entries + {:.5} (r2 {:.3}, {} random patches)",
        r.slope, r.intercept, r.r2, r.samples
    );
    let _ = writeln!(s, "crossings:  {} on {} borders", crossings.len(), {
        let mut b: Vec<u32> = crossings.iter().map(|c| c.border).collect();
        b.dedup();
        b.len()
    });
    let area_walkers: f64 = p.measured.iter().map(|m| m.density).sum();
    let standers: u32 = p.measured.iter().map(|m| m.standers).sum();
    let _ = writeln!(
        s,
        "measured:   mean density {:.4} per m2 over {} patches, {standers} standers",
        area_walkers / p.measured.len().max(1) as f64,
        p.measured.len()
    );
    let _ = writeln!(s, "worst patches (where the error stays):");
    for w in &p.worst {
        let d = w
            .direction_error
            .map(|d| format!(", direction off by {d:.2}"))
            .unwrap_or_default();
        let _ = writeln!(
            s,
            "  #{:<6} cell ({:>3}, {:>3}): requested {:.4}, measured {:.4}{d}",
            w.patch.0, w.cell.col, w.cell.row, w.requested, w.measured
        );
    }
    s
}

fn inspect_trajectories(t: &TrajectoriesFile) -> String {
    let mut s = String::new();
    let h = &t.header;
    let _ = writeln!(s, "stage file: {} (format version {})", h.stage, h.version);
    let _ = writeln!(s, "built from: {}", h.input_hash);
    let m = &t.summary;
    let _ = writeln!(
        s,
        "walkers:    {} trajectories, {:.1} walkers present at any time",
        m.walkers_trajectories, m.walkers_measured
    );
    let _ = writeln!(
        s,
        "            {} pause, {} stay more than one period, {} enter and leave by one border",
        m.pausing, m.multi_period, m.same_border
    );
    let _ = writeln!(s, "standers:   {}", m.standers);
    if let Some(c) = &t.collisions {
        let _ = writeln!(
            s,
            "collisions: {} pushes; {} patches still hold a collision (worst margin {:.3} m)",
            c.iterations,
            c.unconverged.len(),
            c.min_margin_m
        );
        for st in c.unconverged.iter().take(10) {
            use crowd_core::trajectories::StallWith;
            let with = match st.with {
                StallWith::Walker(b) if b == st.walker => "itself a period later".to_string(),
                StallWith::Walker(b) => format!("walker {b}"),
                StallWith::Stander(k) => format!("stander {k}"),
                StallWith::Obstacle(k) => format!("obstacle {k}"),
            };
            let _ = writeln!(
                s,
                "  patch #{}: {:.3} m closer than allowed: walker {} and {with} at t = {:.2} s",
                st.patch, st.margin_m, st.walker, st.t_s
            );
        }
    }
    if let Some(m) = &t.smoothing {
        let _ = writeln!(
            s,
            "smoothing:  {} trajectories smoothed, {} kept as polylines (their curve came too \
             close to someone), {} curve points dropped for straying too far",
            m.smoothed, m.kept_straight, m.dropped_points
        );
    }
    let _ = writeln!(
        s,
        "motion:     {} ({} bytes, {})",
        t.motion.file,
        t.motion.bytes,
        t.motion.hash.short()
    );
    s
}
