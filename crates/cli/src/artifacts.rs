//! What the stages of one command have made or read so far. A stage asks for its inputs here;
//! whatever an earlier stage of the same build made is handed over in memory, anything else is
//! read from the stage files in the folder on first use (and checked against the graph beside
//! it). Values are shared (`Rc`) so a stage can hold several while the next one's result goes
//! in, and taken out (`take_*`) by the last stage that needs them, to free the memory early.

use crate::driver::Split;
use crate::stage::Stage;
use crate::stages;
use anyhow::Result;
use crowd_core::config::PipelineFile;
use crowd_core::maps::MergeFile;
use crowd_core::patterns::{Crossing, HeldCrossings, Patterns};
use crowd_core::trajectories::{PatchMotion, TrajectoriesFile, check_motion};
use crowd_core::{Hash, MergedMaps, PatchGraph};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;

/// A stage's patterns: the file and its crossings.
pub type PatternsOf = (Patterns, HeldCrossings);
/// Stage 3's file as read: the patterns and the world's crossings.
type FileOf = (Patterns, Vec<Crossing>);
/// A trajectories file (stages 4, 5, 6) and its motion.
pub type MotionOf = (TrajectoriesFile, Vec<PatchMotion>);
use crowd_core::trajectories::LazyMotion;

/// The inputs and results of the stages of one command.
pub struct Artifacts<'p> {
    pub pipeline: &'p PipelineFile,
    /// Whether this process builds all, a shard or the gathering (`crowd build --shard`).
    pub split: crate::driver::Split,
    /// The hash of each stage's inputs in this build (skipped or run), by stage name.
    pub hashes: BTreeMap<&'static str, crowd_core::Hash>,
    /// What each patch costs, for dealing patches to shards (stage 5 works it out).
    pub shard_costs: Option<Rc<Vec<u64>>>,
    /// A shard that does only its share of stage 3 (`--shard I/N --until optimize`).
    pub regions_only: bool,
    /// A shard's stage 4 motion: its own patches and their neighbours, the others empty.
    pub shard_matched: Option<Vec<PatchMotion>>,
    /// A shard's stage 5 motion: its own patches and their neighbours, the others empty.
    pub shard_collided: Option<Vec<PatchMotion>>,
    /// The last build's outputs of stages 4-6, read ahead (`crate::reuse::Prefetch`).
    pub previous: crate::reuse::Prefetch,
    /// Where stage files are read from.
    dir: PathBuf,
    /// A stage's file given at another path (a subcommand's `--input`).
    given: Option<(&'static str, PathBuf)>,
    /// The hashes of stage files' bytes, what later stages' input hashes are made of (their
    /// bytes are not kept: the million's `graph.ron` and `patterns.ron` were 75 MB held
    /// through every stage).
    file_hashes: BTreeMap<&'static str, Hash>,
    layers: Option<Rc<Vec<crowd_merge::LayerBytes>>>,
    maps: Option<Rc<MergedMaps>>,
    /// Shared with `PatchGraph::load_shared`'s parse, not a copy of it (the million's graph,
    /// 0.1 GB, was held twice).
    graph: Option<Arc<PatchGraph>>,
    patterns: Option<Rc<PatternsOf>>,
    motion: BTreeMap<&'static str, Rc<MotionOf>>,
    /// Motion this build made but left in files not yet in place (a gathering's stage 6, in
    /// the shards' parts), read a patch at a time when asked for.
    lazy: BTreeMap<&'static str, Rc<(TrajectoriesFile, LazyMotion)>>,
}

impl<'p> Artifacts<'p> {
    /// Nothing made yet; stage files are read from `dir`.
    pub fn new(pipeline: &'p PipelineFile, dir: &Path) -> Artifacts<'p> {
        Artifacts {
            pipeline,
            split: crate::driver::Split::Whole,
            hashes: BTreeMap::new(),
            shard_costs: None,
            regions_only: false,
            shard_matched: None,
            shard_collided: None,
            previous: Default::default(),
            dir: dir.to_path_buf(),
            given: None,
            file_hashes: BTreeMap::new(),
            layers: None,
            maps: None,
            graph: None,
            patterns: None,
            motion: BTreeMap::new(),
            lazy: BTreeMap::new(),
        }
    }

    /// Stage files read beside `path`, which stands for the stage file `name`.
    pub fn beside(pipeline: &'p PipelineFile, name: &'static str, path: &Path) -> Artifacts<'p> {
        let dir = path.parent().filter(|p| !p.as_os_str().is_empty());
        let mut artifacts = Artifacts::new(pipeline, dir.unwrap_or(Path::new(".")));
        artifacts.given = Some((name, path.to_path_buf()));
        artifacts
    }

    /// Where the stage file `name` is read from.
    pub fn path(&self, name: &str) -> PathBuf {
        match &self.given {
            Some((given, path)) if *given == name => path.clone(),
            _ => self.dir.join(name),
        }
    }

    /// The hash of the bytes of the file `stage` made (what later stages' input hashes are
    /// made of), read through once, a piece at a time.
    pub fn file_hash(&mut self, stage: &Stage) -> Result<Hash> {
        if let Some(hash) = self.file_hashes.get(stage.output) {
            return Ok(*hash);
        }
        let path = self.path(stage.output);
        let (_, hash) =
            Hash::of_file(&path).map_err(|e| crowd_core::Error::io(&path, "read", e))?;
        self.file_hashes.insert(stage.output, hash);
        Ok(hash)
    }

    /// Records the hash of the bytes of the file `stage` just made (not yet in place).
    pub fn keep_hash(&mut self, stage: &'static Stage, bytes: &[u8]) {
        self.file_hashes.insert(stage.output, Hash::of(bytes));
    }

    /// The painted layers the pipeline names, read (not decoded) once.
    pub fn layers(&mut self) -> Result<Rc<Vec<crowd_merge::LayerBytes>>> {
        if self.layers.is_none() {
            self.layers = Some(Rc::new(crowd_merge::read_layers(self.pipeline)?));
        }
        Ok(self.layers.clone().expect("just read"))
    }

    pub fn keep_maps(&mut self, maps: MergedMaps) {
        self.maps = Some(Rc::new(maps));
    }

    /// Stage 1's maps, taken out: only stage 2 reads them.
    pub fn take_maps(&mut self) -> Result<Rc<MergedMaps>> {
        match self.maps.take() {
            Some(maps) => Ok(maps),
            None => Ok(Rc::new(
                MergeFile::load(&self.path(stages::MERGE.output))?.1,
            )),
        }
    }

    pub fn made_graph(&mut self, graph: Arc<PatchGraph>) {
        self.graph = Some(graph);
    }

    /// Stage 2's graph.
    pub fn graph(&mut self) -> Result<Arc<PatchGraph>> {
        if self.graph.is_none() {
            self.graph = Some(PatchGraph::load_shared(&self.path(stages::GRAPH.output))?);
        }
        Ok(self.graph.clone().expect("just loaded"))
    }

    /// Keeps the patterns stage 3 made: the world's crossings, or a shard's window of them
    /// ([`Artifacts::shard_window`]).
    pub fn made_patterns(&mut self, patterns: PatternsOf) {
        self.patterns = Some(Rc::new(patterns));
    }

    /// Keeps stage 3's patterns read from `path`, refused unless they fit the graph.
    pub fn found_patterns(&mut self, path: &Path, (patterns, crossings): FileOf) -> Result<()> {
        let graph = self.graph()?;
        crowd_core::patterns::check_crossings(path, &graph, &patterns, &crossings)?;
        self.keep_patterns((patterns, HeldCrossings::whole(crossings)))
    }

    /// Keeps the patterns read from a file: a shard only its window of the crossings.
    fn keep_patterns(&mut self, (patterns, crossings): PatternsOf) -> Result<()> {
        let each = |count: &mut dyn FnMut(&Crossing)| {
            crossings.view().indexed().for_each(|(_, c)| count(c));
        };
        let crossings = match self.shard_window(|graph| walkers_of(graph, each))? {
            Some(borders) => crossings.window(borders),
            None => crossings,
        };
        self.made_patterns((patterns, crossings));
        Ok(())
    }

    /// For a shard of stages 4-6: deals the patches to shards by `walkers` (each patch's, the
    /// world's crossings that enter it, [`walkers_of`], so that every shard deals the same;
    /// counted only here) and gives the borders whose crossings it keeps: those of its patches
    /// and of the two rings of patches round them (its stage 4 matches a ring, and the ring's
    /// keys and stage 6 read the ring's crossings). `None` for any other build, which keeps
    /// them all.
    pub fn shard_window(
        &mut self,
        walkers: impl FnOnce(&PatchGraph) -> Vec<usize>,
    ) -> Result<Option<std::ops::Range<u32>>> {
        let Split::Shard(shard) = self.split else {
            return Ok(None);
        };
        if self.regions_only {
            return Ok(None);
        }
        let graph = self.graph()?;
        let walkers = walkers(&graph);
        let costs = crowd_core::shard::costs(walkers.len(), |p| walkers[p]);
        let own: Vec<usize> = shard.run(&costs).collect();
        let ring = crowd_core::shard::with_neighbours(&graph, &own);
        let reach = crowd_core::shard::with_neighbours(&graph, &ring);
        self.shard_costs = Some(Rc::new(costs));
        Ok(Some(crowd_core::shard::border_window(&graph, &reach)))
    }

    /// Stage 3's patterns and crossings.
    pub fn patterns(&mut self) -> Result<Rc<PatternsOf>> {
        if self.patterns.is_none() {
            let path = self.path(stages::OPTIMIZE.output);
            let patterns = Patterns::load(&path)?;
            self.found_patterns(&path, patterns)?;
        }
        Ok(self.patterns.clone().expect("just loaded"))
    }

    /// Stage 3's patterns and crossings, taken out: for the last stage that reads them (export,
    /// which lets the world's crossings go once its library has their records).
    pub fn take_patterns(&mut self) -> Result<Rc<PatternsOf>> {
        self.patterns()?;
        Ok(self.patterns.take().expect("just loaded"))
    }

    pub fn made_motion(&mut self, stage: &'static Stage, motion: MotionOf) {
        self.motion.insert(stage.output, Rc::new(motion));
    }

    /// Keeps the motion `stage` wrote at `path`, refused unless it has one entry per patch of
    /// the graph.
    pub fn found_motion(
        &mut self,
        stage: &'static Stage,
        path: &Path,
        motion: MotionOf,
    ) -> Result<()> {
        check_motion(path, self.graph()?.patches.len(), &motion.1)?;
        self.made_motion(stage, motion);
        Ok(())
    }

    /// The motion `stage` (match, collide, smooth) made, taken out: each is read by the next
    /// stage only.
    /// What each patch costs, for dealing patches to shards ([`crowd_core::shard::costs`]):
    /// from stage 4's motion when this build has it, else from its file's counts alone (no
    /// trajectory decoded).
    pub fn shard_costs(&mut self) -> Result<Rc<Vec<u64>>> {
        if let Some(costs) = &self.shard_costs {
            return Ok(costs.clone());
        }
        // From stage 3, so that a shard knows its patches before it matches them.
        let (graph, patterns) = (self.graph()?, self.patterns()?);
        let each = |count: &mut dyn FnMut(&Crossing)| {
            patterns.1.view().indexed().for_each(|(_, c)| count(c));
        };
        let walkers = walkers_of(&graph, each);
        let costs = Rc::new(crowd_core::shard::costs(walkers.len(), |p| walkers[p]));
        self.shard_costs = Some(costs.clone());
        Ok(costs)
    }

    /// Whether this build holds `stage`'s motion in memory (made by it, or read already).
    pub fn holds_motion(&self, stage: &'static Stage) -> bool {
        self.motion.contains_key(stage.output)
    }

    /// Keeps the motion `stage` made as left in files, for the stages after it.
    pub fn made_lazy_motion(
        &mut self,
        stage: &'static Stage,
        made: (TrajectoriesFile, LazyMotion),
    ) {
        self.lazy.insert(stage.output, Rc::new(made));
    }

    /// The motion `stage` made and left in files, taken out, if it did.
    pub fn take_lazy_motion(
        &mut self,
        stage: &'static Stage,
    ) -> Option<Rc<(TrajectoriesFile, LazyMotion)>> {
        self.lazy.remove(stage.output)
    }

    /// The motion `stage` made and left in files, if it did.
    pub fn lazy_motion(&self, stage: &'static Stage) -> Option<Rc<(TrajectoriesFile, LazyMotion)>> {
        self.lazy.get(stage.output).cloned()
    }

    pub fn take_motion(&mut self, stage: &'static Stage) -> Result<Rc<MotionOf>> {
        if let Some(lazy) = self.lazy.remove(stage.output) {
            let motion = lazy.1.all()?;
            self.made_motion(stage, (lazy.0.clone(), motion));
        }
        if !self.motion.contains_key(stage.output) {
            let path = self.path(stage.output);
            let loaded = TrajectoriesFile::load_stage(&path, stage.kind, stage.version)?;
            self.found_motion(stage, &path, loaded)?;
        }
        Ok(self.motion.remove(stage.output).expect("just loaded"))
    }
}

/// Each patch's walkers: the crossings that enter it (what dealing patches to shards costs
/// them by, [`crowd_core::shard::costs`]), of the crossings `each` hands to its counter (a
/// list's, or stage 3's walk of the world's, [`crowd_optimize::Outcome::visit_crossings`]).
pub fn walkers_of(graph: &PatchGraph, each: impl FnOnce(&mut dyn FnMut(&Crossing))) -> Vec<usize> {
    let mut walkers = vec![0usize; graph.patches.len()];
    each(&mut |c| walkers[c.ends(graph).1.patch.0 as usize] += 1);
    walkers
}
