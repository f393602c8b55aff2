//! The final motion as export reads it: a patch at a time, from wherever it is.
//!
//! A build that made the motion holds it whole and lends each patch ([`Motion`] for a slice).
//! A gathering build reads each patch from the shards' files and thins it when asked
//! ([`Made`]), so that its export holds the world's motion only as [`Summaries`] (what links,
//! times and boxes need of each trajectory), the library it quantises, and, for `world.glb`,
//! the patches its region's loops walk ([`Held`]). Holding the world's thinned keyframes was
//! most of the million's 10 GB gather.

use crate::characters::TrajectoryRef;
use crowd_core::PatchGraph;
use crowd_core::trajectories::{PatchMotion, Trajectory};
use glam::DVec2;
use rayon::prelude::*;
use std::borrow::Cow;

/// The final motion, thinned ([`crate::simplify`]), one patch at a time, in patch order.
pub trait Motion: Sync {
    fn patches(&self) -> usize;
    /// Patch `p`'s motion: lent, or made (read and thinned) for the caller.
    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>>;
}

impl Motion for [PatchMotion] {
    fn patches(&self) -> usize {
        self.len()
    }

    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
        Ok(Cow::Borrowed(&self[p]))
    }
}

impl Motion for Vec<PatchMotion> {
    fn patches(&self) -> usize {
        self.len()
    }

    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
        Ok(Cow::Borrowed(&self[p]))
    }
}

/// Motion made patch by patch when asked, by `make` (a gathering build: read from the shards'
/// files and thinned). Export asks for each patch twice (its summary, then its library
/// records) and a third time for the patches `world.glb` shows.
pub struct Made<F> {
    patches: usize,
    make: F,
}

impl<F: Fn(usize) -> crowd_core::Result<PatchMotion> + Sync> Made<F> {
    pub fn new(patches: usize, make: F) -> Self {
        Made { patches, make }
    }
}

impl<F: Fn(usize) -> crowd_core::Result<PatchMotion> + Sync> Motion for Made<F> {
    fn patches(&self) -> usize {
        self.patches
    }

    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
        (self.make)(p).map(Cow::Owned)
    }
}

/// What export keeps of a trajectory without its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    pub entry: u32,
    pub exit: u32,
    /// How many keyframes it has.
    pub points: usize,
    /// Its first keyframe's time, and its duration ([`Trajectory::duration`]), s.
    pub start_s: f64,
    pub duration_s: f64,
    /// The box that holds its keyframes, world metres.
    pub lo: DVec2,
    pub hi: DVec2,
}

impl Summary {
    fn of(tr: &Trajectory, origin: DVec2) -> Summary {
        let empty = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        let (lo, hi) = (tr.points.iter()).fold(empty, |(lo, hi), cp| {
            let at = origin + cp.pos;
            (lo.min(at), hi.max(at))
        });
        Summary {
            entry: tr.entry,
            exit: tr.exit,
            points: tr.points.len(),
            start_s: tr.points.first().map_or(0.0, |p| p.t),
            duration_s: tr.duration(),
            lo,
            hi,
        }
    }
}

/// Every trajectory's [`Summary`], numbered patch after patch, and every patch's standers.
#[derive(Debug, Clone, PartialEq)]
pub struct Summaries {
    pub trajectories: Vec<Summary>,
    /// Each patch's standers, patch-local metres.
    pub standers: Vec<Vec<DVec2>>,
    /// The number of each patch's first trajectory.
    pub firsts: Vec<usize>,
}

impl Summaries {
    /// The summaries of `motion`'s patches (in parallel; each patch's are its own).
    pub fn of<M: Motion + ?Sized>(graph: &PatchGraph, motion: &M) -> crowd_core::Result<Self> {
        let per_patch: Vec<crowd_core::Result<(Vec<Summary>, Vec<DVec2>)>> = (0..motion.patches())
            .into_par_iter()
            .map(|p| {
                let m = motion.patch(p)?;
                let origin = graph.world_from_patch(graph.patches[p].cell);
                let trajectories = (m.trajectories.iter())
                    .map(|tr| Summary::of(tr, origin))
                    .collect();
                Ok((trajectories, m.standers.clone()))
            })
            .collect();
        let mut all = Summaries {
            trajectories: Vec::new(),
            standers: Vec::with_capacity(per_patch.len()),
            firsts: Vec::with_capacity(per_patch.len()),
        };
        for part in per_patch {
            let (trajectories, standers) = part?;
            all.firsts.push(all.trajectories.len());
            all.trajectories.extend(trajectories);
            all.standers.push(standers);
        }
        Ok(all)
    }

    /// Each trajectory's patch and place in it, in their order (made from `firsts`, not held:
    /// the million's 2.7 million trajectories' were 43 MB).
    pub fn refs(&self) -> impl Iterator<Item = TrajectoryRef> + '_ {
        let ends = (self.firsts.iter().skip(1).copied()).chain([self.trajectories.len()]);
        (self.firsts.iter().zip(ends).enumerate()).flat_map(|(patch, (&first, end))| {
            (0..end - first).map(move |i| TrajectoryRef::new(patch, i))
        })
    }
}

/// The patches of the final motion that `world.glb` reads keyframes from, held; the others
/// are never read.
pub struct Held<'a> {
    patches: Vec<Option<Cow<'a, PatchMotion>>>,
}

impl<'a> Held<'a> {
    /// The patches of `motion` marked in `wanted`.
    pub fn load<M: Motion + ?Sized>(motion: &'a M, wanted: &[bool]) -> crowd_core::Result<Self> {
        let patches: Vec<crowd_core::Result<Option<Cow<'a, PatchMotion>>>> = (wanted.par_iter())
            .enumerate()
            .map(|(p, &w)| w.then(|| motion.patch(p)).transpose())
            .collect();
        Ok(Held {
            patches: patches.into_iter().collect::<crowd_core::Result<_>>()?,
        })
    }

    /// Trajectory `r`, whose patch must be held.
    pub fn trajectory(&self, r: TrajectoryRef) -> &Trajectory {
        let m = self.patches[r.patch as usize]
            .as_ref()
            .expect("world.glb reads only the patches it asked to hold");
        &m.trajectories[r.index as usize]
    }
}
