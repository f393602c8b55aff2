//! Characters: trajectories linked through the crossings they share. Every crossing is left by
//! exactly one trajectory and entered by exactly one (stage 4's matching, checked by `crowd
//! check`), so following exit -> entry is a permutation of the trajectories, and its cycles are
//! the loops characters walk forever. A loop lasting k periods carries k characters at once.

use crowd_core::trajectories::PatchMotion;

/// A trajectory by patch and place in its patch, numbered patch after patch (32 bits each:
/// one is held for every trajectory of the world through export).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrajectoryRef {
    pub patch: u32,
    pub index: u32,
}

impl TrajectoryRef {
    /// Trajectory `index` of patch `patch` (a world's patches, and a patch's trajectories, are
    /// numbered in 32 bits in every stage file).
    pub fn new(patch: usize, index: usize) -> TrajectoryRef {
        let n = |x: usize| u32::try_from(x).expect("stage files number in 32 bits");
        TrajectoryRef {
            patch: n(patch),
            index: n(index),
        }
    }
}

/// Every trajectory's global number, its successor, and the loops.
#[derive(Debug, Clone, PartialEq)]
pub struct Links {
    pub refs: Vec<TrajectoryRef>,
    /// `next[i]`: the trajectory that enters by trajectory `i`'s exit.
    pub next: Vec<u32>,
    /// Loops, each as its trajectories in walking order, from its lowest-numbered one.
    pub loops: Vec<Vec<usize>>,
}

/// Why trajectories cannot be linked into loops.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkError {
    /// A crossing no trajectory enters by, or two do.
    Entries { crossing: u32, count: usize },
    /// A crossing two trajectories leave by.
    Exits { crossing: u32, count: usize },
    /// A trajectory names a crossing that does not exist.
    UnknownCrossing {
        patch: usize,
        trajectory: usize,
        crossing: u32,
    },
}

impl std::fmt::Display for LinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinkError::Entries { crossing, count } => write!(
                f,
                "crossing {crossing} is entered by {count} trajectories; expected exactly one"
            ),
            LinkError::Exits { crossing, count } => write!(
                f,
                "crossing {crossing} is left by {count} trajectories; expected exactly one"
            ),
            LinkError::UnknownCrossing {
                patch,
                trajectory,
                crossing,
            } => write!(
                f,
                "patch {patch}, trajectory {trajectory}: crossing {crossing} is not in the patterns"
            ),
        }
    }
}

impl std::error::Error for LinkError {}

/// Links the trajectories of `motion` through `crossings` crossings.
pub fn link(motion: &[PatchMotion], crossings: usize) -> Result<Links, LinkError> {
    let ends = motion.iter().enumerate().flat_map(|(patch, m)| {
        (m.trajectories.iter().enumerate())
            .map(move |(index, tr)| (TrajectoryRef::new(patch, index), tr.entry, tr.exit))
    });
    link_ends(ends, crossings)
}

/// Links trajectories given as (where, entry, exit), numbered in the order given, through
/// `crossings` crossings.
pub fn link_ends(
    ends: impl Iterator<Item = (TrajectoryRef, u32, u32)>,
    crossings: usize,
) -> Result<Links, LinkError> {
    let mut refs = Vec::new();
    let mut exit_of = Vec::new();
    let mut entered_by: Vec<Option<u32>> = vec![None; crossings];
    let mut counts = vec![0usize; crossings];
    let mut exits = vec![0usize; crossings];
    for (r, entry, exit) in ends {
        for c in [entry, exit] {
            if c as usize >= crossings {
                return Err(LinkError::UnknownCrossing {
                    patch: r.patch as usize,
                    trajectory: r.index as usize,
                    crossing: c,
                });
            }
        }
        exits[exit as usize] += 1;
        if exits[exit as usize] > 1 {
            return Err(LinkError::Exits {
                crossing: exit,
                count: exits[exit as usize],
            });
        }
        // Each trajectory leaves by a crossing of its own (above), numbered in 32 bits.
        entered_by[entry as usize] = Some(u32::try_from(refs.len()).expect("32-bit crossings"));
        counts[entry as usize] += 1;
        refs.push(r);
        exit_of.push(exit);
    }
    let mut next = Vec::with_capacity(refs.len());
    for &exit in &exit_of {
        match (counts[exit as usize], entered_by[exit as usize]) {
            (1, Some(n)) => next.push(n),
            (count, _) => {
                return Err(LinkError::Entries {
                    crossing: exit,
                    count,
                });
            }
        }
    }
    drop(exit_of);
    let mut seen = vec![false; refs.len()];
    let mut loops = Vec::new();
    for start in 0..refs.len() {
        if seen[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut at = start;
        while !seen[at] {
            seen[at] = true;
            lp.push(at);
            at = next[at] as usize;
        }
        // Each trajectory has one successor and (counts == 1) one predecessor: a permutation,
        // so the walk closes on `start`.
        debug_assert_eq!(at, start);
        loops.push(lp);
    }
    Ok(Links { refs, next, loops })
}
