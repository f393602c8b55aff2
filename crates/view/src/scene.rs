//! What the viewer draws besides the characters, made from the build folder's own stage files:
//! `scene.json` (the patch grid with each patch's requested and measured density, requested
//! direction and obstacles; `crowd check`'s findings; stage 7's edits) and `ground.png` (the
//! merged painting: walker density in green, standers in pink, obstacles dark), one pixel per
//! map pixel, row 0 at the north edge.

use anyhow::{Context, Result};
use crowd_core::PatchGraph;
use crowd_core::maps::MergeFile;
use crowd_core::patterns::Patterns;
use crowd_core::trajectories::TrajectoriesFile;
use serde_json::{Value, json};
use std::path::Path;

/// `scene.json` for the build folder `dir`: every part whose file the folder has.
pub fn scene_json(dir: &Path) -> Result<String> {
    let mut out = serde_json::Map::new();
    let graph_path = dir.join("graph.ron");
    if graph_path.is_file() {
        let graph = PatchGraph::load(&graph_path)?;
        let measured = Patterns::load(&dir.join("patterns.ron"))
            .ok()
            .map(|(p, _)| p.measured);
        out.insert("world".into(), world(&graph));
        out.insert("patches".into(), patches(&graph, measured.as_deref()));
    }
    let check = dir.join("check.ron");
    if check.is_file() {
        let text = std::fs::read_to_string(&check)
            .with_context(|| format!("{}: cannot read", check.display()))?;
        let value: ron::Value = ron::from_str(&text)
            .with_context(|| format!("{}: not a check file", check.display()))?;
        out.insert("check".into(), serde_json::to_value(&value)?);
    }
    let edited = dir.join("edited.ron");
    if edited.is_file() {
        let file: TrajectoriesFile = crowd_core::files::read_ron(&edited)?;
        out.insert("edits".into(), json!(file.edits.unwrap_or_default()));
    }
    Ok(Value::Object(out).to_string())
}

fn world(graph: &PatchGraph) -> Value {
    let w = &graph.world;
    json!({
        "cols": w.cols,
        "rows": w.rows,
        "side": w.patch_side_m,
        "size": [w.size_m.x, w.size_m.y],
        "radius": graph.radius_m,
    })
}

/// Per patch, in the graph's (and the library's) order.
fn patches(graph: &PatchGraph, measured: Option<&[crowd_core::patterns::Measured]>) -> Value {
    let list: Vec<Value> = graph
        .patches
        .iter()
        .enumerate()
        .map(|(i, p)| {
            json!({
                "col": p.cell.col,
                "row": p.cell.row,
                "requested": p.walker_density + p.stander_density,
                "measured": measured.and_then(|m| m.get(i)).map(|m| m.density),
                "direction": p.direction.as_ref().map(|d| [d.dir.x, d.dir.y]),
                "obstacles": p.obstacles.iter().map(|o| [o.min.x, o.min.y, o.max.x, o.max.y]).collect::<Vec<_>>(),
            })
        })
        .collect();
    Value::Array(list)
}

/// The merged painting as a PNG, or `None` when the folder has no `merge.ron`.
pub fn ground_png(dir: &Path) -> Result<Option<Vec<u8>>> {
    let path = dir.join("merge.ron");
    if !path.is_file() {
        return Ok(None);
    }
    let (_, maps) = MergeFile::load(&path)?;
    let (w, h) = (maps.width(), maps.height());
    let top = |values: &[f32]| values.iter().copied().fold(0.0f32, f32::max).max(1e-6);
    let (walkers, standers) = (maps.walkers.as_slice(), maps.standers.as_slice());
    let (wmax, smax) = (top(walkers), top(standers));
    let blocked = maps.blocked.as_slice();
    let mut image = image::RgbImage::new(w, h);
    for (i, px) in image.pixels_mut().enumerate() {
        if blocked[i] {
            *px = image::Rgb([58, 60, 66]);
            continue;
        }
        // Paper white, greened by walker density and pinked by stander density.
        let (a, b) = (walkers[i] / wmax, standers[i] / smax);
        let mix = |paper: f32, walk: f32, stand: f32| {
            (paper * (1.0 - 0.55 * a - 0.35 * b) + walk * 0.55 * a + stand * 0.35 * b) as u8
        };
        *px = image::Rgb([
            mix(236.0, 90.0, 220.0),
            mix(236.0, 170.0, 120.0),
            mix(230.0, 110.0, 170.0),
        ]);
    }
    let mut bytes = Vec::new();
    image::DynamicImage::ImageRgb8(image)
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .context("encoding the ground picture")?;
    Ok(Some(bytes))
}
