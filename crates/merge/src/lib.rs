//! Stage 1, merge: painted layers in, [`MergedMaps`] out.
//!
//! Each kind of layer is merged on its own, weighted by layer weight x pixel alpha (Crowd Art
//! section 5, "Layer Merging"):
//! - `Density` and `Static`: weighted sum of the gray levels (0..1);
//! - `Direction`: the gray level's gradient from dark to bright, as a unit vector, weighted;
//! - `Flow`: the decoded RGBA flow vector (R = east, G = north, 128 = zero), as a unit vector,
//!   weighted by alpha;
//! - `Obstacles`: union of the pixels whose value x alpha reaches the threshold; walker and
//!   stander densities and directions are cleared under them.
//!
//! [`merge`] is the pure core; [`read_layers`], [`decode`] and [`write`] are the I/O edge.
//! [`decode_flow_map`] reads a flow edit's map (stage 7) with the same checks.

mod flow_map;
mod layer;
mod paint;

pub use flow_map::decode_flow_map;
pub use layer::{LayerBytes, PaintedLayer, Raster, decode, read_layers};
pub use paint::merge;

use crowd_core::config::PipelineFile;
use crowd_core::files::{self, Header, SideFile};
use crowd_core::maps::{LayerRecord, MapsSummary, MergeFile, MergedMaps};
use crowd_core::{Hash, Hasher, Result};
use std::path::Path;

/// The hash of everything stage 1 reads: layer contents, kinds, weights, scale and settings.
/// Paths are left out on purpose: moving a layer file does not make the build stale.
pub fn input_hash(pipeline: &PipelineFile, layers: &[LayerBytes]) -> Hash {
    let p = &pipeline.pipeline;
    let mut h = Hasher::new(MergeFile::STAGE, MergeFile::VERSION);
    h.value("meters_per_pixel", &p.scene.meters_per_pixel)
        .value("settings", &p.merge);
    for layer in layers {
        h.value("kind", &layer.spec.kind)
            .value("weight", &layer.spec.weight)
            .part("content", layer.hash.to_string().as_bytes());
    }
    h.finish()
}

/// Figures of merged maps.
pub fn summarize(maps: &MergedMaps) -> MapsSummary {
    let count = |values: &mut dyn Iterator<Item = bool>| values.filter(|&b| b).count() as u64;
    MapsSummary {
        walker_pixels: count(&mut maps.walkers.as_slice().iter().map(|&v| v > 0.0)),
        stander_pixels: count(&mut maps.standers.as_slice().iter().map(|&v| v > 0.0)),
        directed_pixels: count(&mut maps.flow_weight.as_slice().iter().map(|&v| v > 0.0)),
        blocked_pixels: count(&mut maps.blocked.as_slice().iter().copied()),
    }
}

/// Stage 1's files, encoded but not yet written: the side file first, then the RON that names it.
pub struct Encoded {
    pub file: MergeFile,
    pub writes: files::Writes,
}

impl Encoded {
    /// The bytes of the RON file (what stage 2's input hash is made of).
    pub fn ron_bytes(&self) -> &[u8] {
        &self.writes.last().expect("the RON file is written last").1
    }

    /// Writes every file atomically, side file first.
    pub fn write(&self) -> Result<()> {
        files::write_all(&self.writes)
    }
}

/// Encodes `out` (RON) and its side file (`.bin` beside it).
pub fn encode(
    out: &Path,
    pipeline: &PipelineFile,
    layers: &[LayerBytes],
    decoded: &[PaintedLayer],
    input_hash: Hash,
    maps: &MergedMaps,
) -> Encoded {
    let bytes = maps.to_bytes();
    let (side, record) = SideFile::beside(out, &bytes);
    let file = MergeFile {
        header: Header::new(MergeFile::STAGE, MergeFile::VERSION, input_hash),
        width: maps.width(),
        height: maps.height(),
        meters_per_pixel: pipeline.pipeline.scene.meters_per_pixel,
        layers: layers
            .iter()
            .zip(decoded)
            .map(|(l, d)| LayerRecord {
                kind: l.spec.kind,
                path: l.spec.path.display().to_string(),
                weight: l.spec.weight,
                format: d.raster.format(),
                hash: l.hash,
            })
            .collect(),
        summary: summarize(maps),
        grids: record,
    };
    let ron = files::to_stage_ron(&file).into_bytes();
    Encoded {
        file,
        writes: vec![(side, bytes), (out.to_path_buf(), ron)],
    }
}
