//! Connected components: patches that people can walk between through open borders.

use crowd_core::patch_graph::Component;
use crowd_core::{Border, Patch};
use petgraph::unionfind::UnionFind;

/// Labels every patch with its component, numbered in order of each component's first patch,
/// and sums what each component requests.
pub fn label(patches: &mut [Patch], borders: &[Border], area: f64) -> Vec<Component> {
    let mut sets = UnionFind::<u32>::new(patches.len());
    for border in borders.iter().filter(|b| !b.open.is_empty()) {
        sets.union(border.a.0, border.b.0);
    }
    let mut label_of_root = vec![u32::MAX; patches.len()];
    let mut components: Vec<Component> = Vec::new();
    for patch in patches.iter_mut() {
        let root = sets.find(patch.id.0) as usize;
        if label_of_root[root] == u32::MAX {
            label_of_root[root] = components.len() as u32;
            components.push(Component {
                id: components.len() as u32,
                patches: 0,
                walkers: 0.0,
                standers: 0.0,
            });
        }
        let c = &mut components[label_of_root[root] as usize];
        patch.component = c.id;
        c.patches += 1;
        c.walkers += patch.walker_density * area;
        c.standers += patch.stander_density * area;
    }
    components
}
