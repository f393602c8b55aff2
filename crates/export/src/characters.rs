//! Characters: trajectories linked through the crossings they share. Every crossing is left by
//! exactly one trajectory and entered by exactly one (stage 4's matching, checked by `crowd
//! check`), so following exit -> entry is a permutation of the trajectories, and its cycles are
//! the loops characters walk forever. A loop lasting k periods carries k characters at once.

use crowd_core::trajectories::PatchMotion;

/// A trajectory by patch and place in its patch, numbered patch after patch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrajectoryRef {
    pub patch: usize,
    pub index: usize,
}

/// Every trajectory's global number, its successor, and the loops.
#[derive(Debug, Clone, PartialEq)]
pub struct Links {
    pub refs: Vec<TrajectoryRef>,
    /// `next[i]`: the trajectory that enters by trajectory `i`'s exit.
    pub next: Vec<usize>,
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
    let mut refs = Vec::new();
    let mut entered_by: Vec<Option<usize>> = vec![None; crossings];
    let mut counts = vec![0usize; crossings];
    let mut exits = vec![0usize; crossings];
    for (patch, m) in motion.iter().enumerate() {
        for (index, tr) in m.trajectories.iter().enumerate() {
            for c in [tr.entry, tr.exit] {
                if c as usize >= crossings {
                    return Err(LinkError::UnknownCrossing {
                        patch,
                        trajectory: index,
                        crossing: c,
                    });
                }
            }
            exits[tr.exit as usize] += 1;
            if exits[tr.exit as usize] > 1 {
                return Err(LinkError::Exits {
                    crossing: tr.exit,
                    count: exits[tr.exit as usize],
                });
            }
            entered_by[tr.entry as usize] = Some(refs.len());
            counts[tr.entry as usize] += 1;
            refs.push(TrajectoryRef { patch, index });
        }
    }
    let traj = |r: &TrajectoryRef| &motion[r.patch].trajectories[r.index];
    let mut next = Vec::with_capacity(refs.len());
    for r in &refs {
        let exit = traj(r).exit;
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
            at = next[at];
        }
        // Each trajectory has one successor and (counts == 1) one predecessor: a permutation,
        // so the walk closes on `start`.
        debug_assert_eq!(at, start);
        loops.push(lp);
    }
    Ok(Links { refs, next, loops })
}
