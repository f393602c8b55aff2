//! Stage 8, export: the final trajectories (stage 6's, or stage 7's) as what engines load.
//!
//! - [`library`]: the binary patch library that `crowd-runtime` plays (`FORMAT.md`): patches
//!   in their places, patterns, standers, trajectories quantised in patch-local space and time,
//!   and the links that keep a character's identity from patch to patch.
//! - [`glb`]: `world.glb`, the same characters as a glTF 2.0 scene with one looping clip.
//! - [`characters`]: those links as loops, the one notion of "a character" both outputs share.
//! - [`simplify`]: both are made from the keyframes an engine needs, within `simplify_mm` of
//!   stage 6's.
//! - [`motion`]: those keyframes a patch at a time, held or read when asked.
//! - [`spill`]: a large library's points kept in a scratch file as they are made.

pub mod characters;
pub mod glb;
pub mod library;
pub mod motion;
pub mod simplify;
pub mod spill;

use crowd_core::{Hash, Hasher};

/// The stage name in `export.ron`'s header.
pub const STAGE: &str = "export";
pub const VERSION: u32 = 11;

/// What stage 8 reads of a pipeline besides its input files.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Inputs {
    pub period_s: f64,
    pub seed: u64,
    pub settings: crowd_core::config::ExportSettings,
}

/// What stage 8 reads of a pipeline.
pub fn inputs(pipeline: &crowd_core::config::PipelineFile) -> Inputs {
    let p = &pipeline.pipeline;
    Inputs {
        period_s: p.period_s,
        seed: p.seed,
        settings: p.export.clone(),
    }
}

/// The hash of stage 8's inputs: the graph, patterns and final trajectories' files (their
/// bytes' hashes) and settings.
pub fn input_hash(graph: &Hash, patterns: &Hash, trajectories: &Hash, inputs: &Inputs) -> Hash {
    Hasher::new(STAGE, VERSION)
        .file_hash("graph file", graph)
        .file_hash("patterns file", patterns)
        .file_hash("trajectories file", trajectories)
        .value("inputs", inputs)
        .finish()
}

/// The library's file name beside `export.ron`.
pub const LIBRARY_FILE: &str = "library.crowd";
/// The glTF world's file name beside `export.ron`.
pub const GLB_FILE: &str = "world.glb";

/// `export.ron`: what stage 8 wrote and the figures an engine programmer asks first.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExportFile {
    pub header: crowd_core::files::Header,
    /// The binary patch library (`FORMAT.md`), its size and content hash.
    pub library: String,
    pub library_bytes: u64,
    pub library_hash: Hash,
    /// The glTF 2.0 world, its size and content hash, and the region it holds (None: all).
    pub gltf: String,
    pub gltf_bytes: u64,
    pub gltf_hash: Hash,
    pub gltf_region: Option<(f64, f64, f64, f64)>,
    pub walkers: u64,
    pub standers: u64,
    /// Loops of linked trajectories; a loop of k periods carries k walkers.
    pub loops: u64,
    pub points: u64,
    /// Worst-case error of the library against stage 6 (the keyframes dropped, then
    /// quantisation): metres, seconds.
    pub position_error_m: f64,
    pub time_error_s: f64,
}

impl ExportFile {
    pub const STAGE: &'static str = STAGE;
    pub const VERSION: u32 = VERSION;

    /// How the library beside `path` (this manifest) differs from the one it names, if it does.
    pub fn library_differs(&self, path: &std::path::Path) -> Option<String> {
        differs(path, &self.library, self.library_bytes, self.library_hash)
    }

    /// How the glTF world beside `path` differs from the one it names, if it does.
    pub fn gltf_differs(&self, path: &std::path::Path) -> Option<String> {
        differs(path, &self.gltf, self.gltf_bytes, self.gltf_hash)
    }
}

/// How the file `name` beside the manifest `path` differs from `bytes` bytes hashing to `hash`.
fn differs(path: &std::path::Path, name: &str, bytes: u64, hash: Hash) -> Option<String> {
    let manifest = path.display();
    match Hash::of_file(&path.with_file_name(name)) {
        Ok(found) if found == (bytes, hash) => None,
        Ok((n, h)) => Some(format!(
            "is {n} bytes with hash {}, but {manifest} names {bytes} bytes with hash {}: it \
             changed since stage 8 wrote it (build again)",
            h.short(),
            hash.short()
        )),
        Err(e) => Some(format!(
            "cannot be read ({e}), but {manifest} names it (build again)"
        )),
    }
}

/// Everything stage 8 makes, in memory.
pub struct Export {
    pub library: LibraryBytes,
    pub glb: Vec<u8>,
    pub manifest: Manifest,
}

/// `export.ron` but the library's size and hash, which are known once its bytes are made.
#[derive(Debug, Clone, PartialEq)]
pub struct Manifest(ExportFile);

/// `library.crowd` as stage 8 hands it over.
#[derive(Debug)]
pub enum LibraryBytes {
    /// Its bytes, made beside `world.glb`.
    Held(Vec<u8>),
    /// A large library's records, to be written a piece at a time
    /// (`crowd_runtime::Library::write_to`): the million's 0.9 GB were held beside them.
    Records(crowd_runtime::Library),
    /// Its records but the points, which are in a scratch file ([`Handing::Spilled`]), to be
    /// written a piece at a time (`crowd_runtime::Library::write_with_points`).
    Spilled(crowd_runtime::Library, spill::Spilled),
    /// Its size and hash: its bytes were handed over (with their hash) as soon as they were
    /// made ([`Handing::Handed`]), for whoever took them to write.
    Handed(u64, Hash),
}

impl Manifest {
    /// `export.ron`, for a library of `bytes` bytes that hash to `hash`.
    pub fn file(self, (bytes, hash): (u64, Hash)) -> ExportFile {
        ExportFile {
            library_bytes: bytes,
            library_hash: hash,
            ..self.0
        }
    }

    pub fn gltf_hash(&self) -> Hash {
        self.0.gltf_hash
    }
}

/// Why stage 8 cannot export a build.
#[derive(Debug)]
pub enum ExportError {
    Library(library::LibraryError),
    /// A patch of the final motion could not be read.
    Motion(crowd_core::Error),
    /// The scratch file of the library's points could not be written or read.
    Scratch(std::io::Error),
}

impl std::fmt::Display for ExportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ExportError::Library(e) => e.fmt(f),
            ExportError::Motion(e) => e.fmt(f),
            ExportError::Scratch(e) => write!(f, "the scratch file of the library's points: {e}"),
        }
    }
}

impl std::error::Error for ExportError {}

impl From<library::LibraryError> for ExportError {
    fn from(e: library::LibraryError) -> Self {
        ExportError::Library(e)
    }
}

impl From<crowd_core::Error> for ExportError {
    fn from(e: crowd_core::Error) -> Self {
        ExportError::Motion(e)
    }
}

/// How far [`simplify::motion`] may move a keyframe for `inputs`, metres.
pub fn tolerance_m(inputs: &Inputs) -> f64 {
    inputs.settings.simplify_mm * 1e-3
}

/// Libraries of fewer points than this are made into bytes beside `world.glb` (painting's has
/// 9.3 million; the million's 96.5 million are handed over as records, [`Handing`]).
const POINTS_BYTES_BESIDE_GLB: usize = 32 << 20;

/// How stage 8 hands `library.crowd` over.
#[derive(Clone, Copy)]
pub enum Handing<'a> {
    /// Its bytes, made beside `world.glb`, for a library under 32 million points; a larger
    /// one's records ([`LibraryBytes`]).
    BySize,
    /// As [`Handing::BySize`], but the bytes and their hash are given to this as soon as they
    /// are made, not held until `world.glb` is done: its longest loop keeps one core busy
    /// while the other is idle, time in which they can be written (painting's stroke: 88 MB, a
    /// quarter of a second that its check waited for). A larger library's records are handed
    /// over as with [`Handing::BySize`].
    Handed(&'a (dyn Fn(Vec<u8>, Hash) + Sync)),
    /// Its records, whatever its size (the tests of [`LibraryBytes::Records`]).
    Records,
    /// Its records but the points, kept in a scratch file in this folder as they are made,
    /// whatever its size: a gathering build writes every file that grows with the world a
    /// piece at a time and holds none of them (the million's points: 0.77 GB), and its tests
    /// then see that path on small worlds.
    Spilled(&'a std::path::Path),
}

/// Stage 8's pure core: the library of the final trajectories, and its manifest. `motion` is
/// the final motion thinned out by [`simplify::motion`] (or [`simplify::patch`] patch by patch)
/// with [`tolerance_m`], held or made a patch at a time when asked ([`motion::Made`]). The
/// crossings are let go once the library has their records, before `world.glb`.
pub fn export<M: motion::Motion>(
    graph: &crowd_core::PatchGraph,
    crossings: Vec<crowd_core::patterns::Crossing>,
    motion: &M,
    inputs: &Inputs,
    hash: Hash,
    handing: Handing,
) -> Result<Export, ExportError> {
    let spill = match handing {
        Handing::Spilled(dir) => Some(spill::Spill::create_in(dir)?),
        _ => None,
    };
    let tolerance_m = tolerance_m(inputs);
    let summaries = motion::Summaries::of(graph, motion)?;
    let ends = (summaries.refs().zip(&summaries.trajectories)).map(|(r, s)| (r, s.entry, s.exit));
    let links =
        characters::link_ends(ends, crossings.len()).map_err(library::LibraryError::Links)?;
    let mut short = [0u8; 8];
    short.copy_from_slice(&hash.as_bytes()[..8]);
    let (period_s, seed) = (inputs.period_s, inputs.seed);
    let (mut lib, eased_m, spilled) = match spill {
        Some(mut spill) => {
            let made = (graph, &crossings[..], motion, &summaries, &links);
            let (lib, eased_m) = library::build_into(made, (period_s, seed, short), &mut spill)?;
            (lib, eased_m, Some(spill.finish()?))
        }
        None => {
            let (lib, eased_m) = library::build(
                graph, &crossings, motion, &summaries, &links, period_s, seed, short,
            )?;
            (lib, eased_m, None)
        }
    };
    drop(crossings);
    let points = spilled.as_ref().map_or(lib.points.len(), |s| s.section().0);
    let region = inputs.settings.gltf_region;
    lib.world.turn_rate_deg_s = inputs.settings.turn_rate_deg_s as f32;
    let glb = || {
        glb::world_glb(&glb::World {
            graph,
            summaries: &summaries,
            motion,
            links: &links,
            period_s: inputs.period_s,
            seed: inputs.seed,
            input_hash: hash.to_string(),
            region,
            library: match &spilled {
                Some(s) => glb::LibraryRef::Spilled(&lib, s),
                None => glb::LibraryRef::Held(&lib),
            },
        })
    };
    // The library's bytes beside `world.glb`: the glTF's longest loop keeps one thread busy
    // long after the others are done (painting's stroke: 0.2 s). But a large library's are not
    // made here: its records are handed over, to be written a piece at a time. Made beside the
    // glTF, its bytes raised the million's peak by their size (0.9 GB); made after it, they
    // were held beside the records (0.9 GB again).
    let hand = match handing {
        Handing::Handed(to) => Some(to),
        _ => None,
    };
    let beside =
        matches!(handing, Handing::BySize | Handing::Handed(_)) && points < POINTS_BYTES_BESIDE_GLB;
    let (bytes, glb) = if beside {
        let made = || {
            let bytes = lib.to_bytes();
            match hand {
                Some(to) => {
                    let made = (bytes.len() as u64, Hash::of(&bytes));
                    to(bytes, made.1);
                    Err(made)
                }
                None => Ok(bytes),
            }
        };
        let (bytes, glb) = rayon::join(made, glb);
        (Some(bytes), glb?)
    } else {
        (None, glb()?)
    };
    let file = ExportFile {
        header: crowd_core::files::Header::new(STAGE, VERSION, hash),
        library: LIBRARY_FILE.to_string(),
        // Filled in by `Manifest::file`, once the library's bytes are made.
        library_bytes: 0,
        library_hash: Hash::of(&[]),
        gltf: GLB_FILE.to_string(),
        gltf_bytes: glb.len() as u64,
        gltf_hash: Hash::of(&glb),
        gltf_region: inputs.settings.gltf_region,
        walkers: lib.walkers(),
        standers: lib.standers.len() as u64,
        loops: lib.characters.len() as u64,
        points: points as u64,
        position_error_m: tolerance_m
            + graph.world.patch_side_m * library::POSITION_ERROR_SHARE
            + eased_m,
        // Rounding, and a tick more where a point was eased (`library::ease_ticks`).
        time_error_s: if eased_m > 0.0 { 1.5 } else { 0.5 } * crowd_runtime::TICK_S,
    };
    let library = match (bytes, spilled) {
        (Some(Ok(bytes)), _) => LibraryBytes::Held(bytes),
        (Some(Err((size, hash))), _) => LibraryBytes::Handed(size, hash),
        (None, Some(spilled)) => LibraryBytes::Spilled(lib, spilled),
        (None, None) => LibraryBytes::Records(lib),
    };
    Ok(Export {
        library,
        glb,
        manifest: Manifest(file),
    })
}

/// Stage 8's files: the library (unless it was handed over already), `world.glb`, then
/// `export.ron` (written last, so that a manifest always names a library that is there). A
/// large library's bytes are made here, whole: a build writes them a piece at a time instead
/// (`crowd build`'s export).
pub fn writes(
    out: &std::path::Path,
    export: Export,
) -> Result<(crowd_core::files::Writes, ExportFile), ExportError> {
    let dir = out.parent().unwrap_or(std::path::Path::new("."));
    let Export {
        library,
        glb,
        manifest,
    } = export;
    let library = match library {
        LibraryBytes::Held(bytes) => bytes,
        LibraryBytes::Handed(size, hash) => {
            let file = manifest.file((size, hash));
            let ron = crowd_core::files::to_stage_ron(&file).into_bytes();
            let writes = vec![(dir.join(GLB_FILE), glb), (out.to_path_buf(), ron)];
            return Ok((writes, file));
        }
        LibraryBytes::Records(lib) => lib.to_bytes(),
        LibraryBytes::Spilled(lib, spilled) => {
            let mut bytes = Vec::new();
            let points = |sink: &mut dyn FnMut(&[u8]) -> std::io::Result<()>| spilled.copy_to(sink);
            let written = lib.write_with_points(spilled.section(), points, |piece| {
                bytes.extend_from_slice(piece);
                Ok(())
            });
            written.map_err(ExportError::Scratch)?;
            bytes
        }
    };
    let file = manifest.file((library.len() as u64, Hash::of(&library)));
    let ron = crowd_core::files::to_stage_ron(&file).into_bytes();
    let writes = vec![
        (dir.join(LIBRARY_FILE), library),
        (dir.join(GLB_FILE), glb),
        (out.to_path_buf(), ron),
    ];
    Ok((writes, file))
}
