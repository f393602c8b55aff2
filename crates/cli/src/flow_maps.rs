//! The flow maps stage 7's `FlowMap` edits name: read (their bytes go into the stage's hash)
//! and decoded (`crowd_merge::decode_flow_map`), at the I/O edge of the stage.

use anyhow::Result;
use crowd_core::PatchGraph;
use crowd_core::config::{EditKind, PipelineFile};
use std::path::PathBuf;
use std::sync::Arc;

/// A flow map's edit (its index in `edits`), file and bytes.
pub struct MapFile {
    pub edit: usize,
    pub path: PathBuf,
    pub bytes: Vec<u8>,
}

/// Reads every flow map the edits name, in the order of the edits; a file that cannot be read
/// is an error at its edit's `map` field.
pub fn read(pipeline: &PipelineFile) -> Result<Vec<MapFile>> {
    let mut out = Vec::new();
    for (k, edit) in pipeline.pipeline.edits.iter().enumerate() {
        let EditKind::FlowMap { map, .. } = &edit.kind else {
            continue;
        };
        let path = pipeline.resolve(map);
        let bytes = std::fs::read(&path).map_err(|e| {
            pipeline.field_error(
                &format!("edits[{k}].kind.map"),
                format!(
                    "(edit `{}`) names the flow map `{}`, which cannot be read ({}): {e}",
                    edit.name,
                    map.display(),
                    path.display()
                ),
            )
        })?;
        out.push(MapFile {
            edit: k,
            path,
            bytes,
        });
    }
    Ok(out)
}

/// Decodes the maps `read` found, over the layers' pixels (the graph's world size at
/// `scene.meters_per_pixel`), for `crowd_moments::Inputs::flow_maps`.
pub fn decode(
    pipeline: &PipelineFile,
    graph: &PatchGraph,
    files: Vec<MapFile>,
) -> Result<Vec<(usize, Arc<crowd_core::flow_map::VelocityMap>)>> {
    let mpp = pipeline.pipeline.scene.meters_per_pixel;
    let size = graph.world.size_m / mpp;
    let pixels = (size.x.round() as u32, size.y.round() as u32);
    files
        .into_iter()
        .map(|f| {
            let edit = &pipeline.pipeline.edits[f.edit];
            let EditKind::FlowMap { speed_m_s, .. } = edit.kind else {
                unreachable!("`read` keeps the FlowMap edits only");
            };
            let map =
                crowd_merge::decode_flow_map(f.path, f.bytes, speed_m_s, mpp, pixels, &edit.name)?;
            Ok((f.edit, Arc::new(map)))
        })
        .collect()
}
