//! The memory budget of a build, checked before any stage runs: a build that would need more
//! than the machine has (or than `--max-memory` allows) is refused at once, naming the
//! settings that size it, instead of being killed by the system an hour in.
//!
//! The estimate is a model fitted to measured peaks (`timings.ron`'s `peak_mb`, release build,
//! 2026-12-04): the stage files of stages 4 to 8 hold every walker's points over one period,
//! so the peak grows with the walkers, and with the period less than in proportion (a longer
//! period holds longer trajectories, not more of them; stage 6 samples curves where they bend).
//!
//! | build | walkers | period | peak measured | estimate |
//! | --- | ---: | ---: | ---: | ---: |
//! | bands | 1,100 | 20 s | 50 MB | 79 MB |
//! | ring | 4,800 | 20 s | 199 MB | 208 MB |
//! | city | 5,000 (+160 standers) | 20 s | 223 MB | 221 MB |
//! | painting | 95,000 | 20 s | 2.81-3.39 GB | 3.37 GB |
//! | bands, period 600 s | 1,100 | 600 s | 313 MB | 336 MB |
//!
//! A build split over processes is sized by its part (2026-12-06, the largest stage peak of
//! `timings.ron`, release; not `/usr/bin/time`'s, which is the last stage's since the build
//! resets the peak at each stage): a shard holds its stage 3 of the world, the regions taken
//! from the shards' parts and put together (700 bytes a walker) or, with the world one region,
//! solved (6.3 kB a walker), and a little of its own patches (500 bytes a walker: it matches,
//! clears and smooths them a patch at a time, and streams its parts); a gather holds what its
//! export and check do: the library's records, the summaries and links, and a part of the
//! points (the longest loop's, a strip's), about 1.75 kB a walker since neither holds the
//! library's points (issue 20's thirteenth part; 2.3 kB before), but a world whose stage 6 side
//! file is under a gibibyte (about 244,000 walkers) is checked in its three forms at once, for
//! speed (12.5 kB a walker). The million's rows were measured again after issue 20's
//! thirteenth part, its gather after the fourteenth (BENCHMARKS.md): 1.75 kB a walker is kept,
//! as the longest loop's share of a world's points (37 % at the million) is the painting's.
//!
//! | build | walkers | peak measured | estimate |
//! | --- | ---: | ---: | ---: |
//! | painting (one region), a shard of 4 (`--threads 1`) | 95,000 | 599 MB | 650 MB |
//! | painting (one region), a shard of 8 | 95,000 | 596-599 MB | 644 MB |
//! | the million (regions of 16), a shard of 8 | 1,016,000 | 0.46-0.49 GB (681-693 MB before issue 20's fifteenth part, 0.53-0.58 GB before its sixteenth) | 0.82 GB |
//! | painting, the gather of 4 shards | 95,000 | 1.14-1.17 GB | 1.23 GB |
//! | the million, the gather of 8 shards | 1,016,000 | 1.10-1.13 GB (1.30-1.38 GB before) | 1.82 GB |
//!
//! A build that stops early (`--until`, or a shard's regions step) holds only what its last
//! stage does of the world (the million's stages on one thread, `timings.ron`, 2026-12-06):
//!
//! | last stage | peak measured | estimate |
//! | --- | ---: | ---: |
//! | merge or graph (the graph) | 331 MB | 345 MB |
//! | optimize, whole (every region's result) | 0.73-0.91 GB | 0.95 GB |
//! | optimize, a shard's regions | 0.23-0.33 GB | 0.95 GB |
//! | optimize, painting as one region, one thread | 598 MB | 638 MB |
//! | match, whole (every patch's lines) | 1.23 GB | 1.31 GB |

use crate::driver::Split;
use crowd_core::config::{LayerKind, People, PipelineFile};

/// Memory of a build whatever its size, bytes: the binary, the maps, the graph.
const BASE: f64 = 40e6;
/// Peak bytes per walker (or stander) at a 20 s period.
const PER_WALKER: f64 = 35e3;
/// How the peak grows with the period: (period / 20 s) to this power.
const PERIOD_POWER: f64 = 0.6;

/// Peak bytes per walker of a build that stops after stage 2 (the graph), stage 3 (the
/// patterns, every region's result) or stage 4 (every patch's lines and standers).
const UNTIL_GRAPH_PER_WALKER: f64 = 300.0;
const UNTIL_MATCH_PER_WALKER: f64 = 1250.0;
/// Stage 3's peak bytes per walker of the world: cut into regions (`optimize.region_patches`:
/// every region's result put together, the regions solved a few at a time), or one region
/// (the world's problem solved at once).
const STAGE3_REGIONS_PER_WALKER: f64 = 900.0;
const STAGE3_ONE_REGION_PER_WALKER: f64 = 6.3e3;
/// A shard's stage 3 in its patches' step, bytes per walker of the world: every region taken
/// from the shards' parts and put together.
const SHARD_STAGE3_PER_WALKER: f64 = 700.0;
/// A shard's peak bytes per walker of its own (its patches' stages 4 to 6), beside its stage 3.
const SHARD_PER_OWN_WALKER: f64 = 500.0;
/// A gather's peak bytes per walker, when its check takes the world a strip at a time.
const GATHER_PER_WALKER: f64 = 1.75e3;
/// A gather's peak bytes per walker, when its check judges the world's three forms at once.
const GATHER_PER_WALKER_AT_ONCE: f64 = 12.5e3;
/// The walkers of the largest world whose check judges its three forms at once (its stage 6
/// side file, about 4.4 kB a walker, under `check::SMALL_WORLD_BYTES`).
const AT_ONCE_WALKERS: f64 = 244e3;

/// The estimated peak memory of building `pipeline` (or its part `split`) up to the stage
/// numbered `last` (8: all of it), bytes.
pub fn estimate(pipeline: &PipelineFile, split: Split, last: u8) -> f64 {
    let p = &pipeline.pipeline;
    let w = characters(pipeline);
    let per_period = (p.period_s / 20.0).powf(PERIOD_POWER);
    let stage3 = w * match p.optimize.region_patches {
        Some(_) => STAGE3_REGIONS_PER_WALKER,
        None => STAGE3_ONE_REGION_PER_WALKER,
    };
    let held = match (split, last) {
        (_, ..=2) => w * UNTIL_GRAPH_PER_WALKER,
        (_, 3) => stage3,
        (Split::Whole, 4) => stage3.max(w * UNTIL_MATCH_PER_WALKER),
        (Split::Whole, _) => w * PER_WALKER,
        (Split::Shard(shard), _) => {
            let stage3 = match p.optimize.region_patches {
                Some(_) => w * SHARD_STAGE3_PER_WALKER,
                None => stage3,
            };
            stage3 + w / f64::from(shard.count()) * SHARD_PER_OWN_WALKER
        }
        // A larger world's check goes a strip at a time, and holds less than the largest one
        // judged at once: the million's gather took 2.1 GB, under the 3.05 GB estimated for a
        // world of 244,000 walkers checked at once.
        (Split::Gather, _) if w <= AT_ONCE_WALKERS => w * GATHER_PER_WALKER_AT_ONCE,
        (Split::Gather, _) => w * GATHER_PER_WALKER,
    };
    BASE + held * per_period
}

/// What of the build `split` is, for a refusal.
fn part(split: Split) -> String {
    match split {
        Split::Whole => "the build".to_string(),
        Split::Shard(s) => format!("shard {}/{}", s.index(), s.count()),
        Split::Gather => "the gather".to_string(),
    }
}

/// The characters a build may place: the totals, or with `people: PerSquareMetre(..)` what
/// the paint asks (each `Density` and `Static` layer's paint summed over its pixels, times its
/// weight, the density and the pixel's area; a layer that cannot be read counts as painted
/// full, and merge will say what is wrong with it).
fn characters(pipeline: &PipelineFile) -> f64 {
    let p = &pipeline.pipeline;
    let People::PerSquareMetre { walkers, standers } = p.people else {
        return p.walkers as f64 + p.standers as f64;
    };
    let rho = p.optimize.rho_max;
    let pixel_m2 = p.scene.meters_per_pixel.powi(2);
    p.scene
        .layers
        .iter()
        .filter_map(|l| {
            let per_m2 = match l.kind {
                LayerKind::Density => walkers.min(rho),
                LayerKind::Static => standers.min(rho),
                _ => return None,
            };
            let path = pipeline.resolve(&l.path);
            let paint = match image::open(&path) {
                Ok(image) => image.to_luma32f().pixels().map(|v| f64::from(v.0[0])).sum(),
                Err(_) => {
                    image::image_dimensions(&path).map_or(0.0, |(w, h)| f64::from(w) * f64::from(h))
                }
            };
            Some(paint * l.weight.max(0.0) * per_m2 * pixel_m2)
        })
        .sum()
}

/// The memory a build may take by default: the machine's (`MemTotal`), where the system says.
pub fn machine_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    crate::memory::kb_field(&info, "MemTotal:")
}

/// Refuses `pipeline` (or its part `split`, up to the stage numbered `last`) when its
/// estimated peak passes `limit` bytes (`--max-memory`, else the machine's memory; no limit
/// where neither is known).
pub fn check(
    pipeline: &PipelineFile,
    (split, last): (Split, u8),
    limit: Option<u64>,
) -> crowd_core::Result<()> {
    let (limit, source) = match limit {
        Some(l) => (l, "--max-memory"),
        None => match machine_memory() {
            Some(l) => (l, "this machine's memory"),
            None => return Ok(()),
        },
    };
    let need = estimate(pipeline, split, last);
    let part = part(split);
    // Shards hold a part of the world; a gather holds what its check judges of all of it.
    let split_it = match split {
        Split::Whole => " split the build into shards (`--shard I/N`, then `--gather`),",
        Split::Shard(_) => " split the build into more shards,",
        Split::Gather => "",
    };
    if need <= limit as f64 {
        return Ok(());
    }
    let p = &pipeline.pipeline;
    if let People::PerSquareMetre { .. } = p.people {
        return Err(pipeline.field_error(
            "people",
            format!(
                "asks for about {:.0} characters as the layers are painted, over a {} s \
                 period: {part} could need about {} at peak, more than the {} of \
                 {source}; lower the densities (or `period_s`),{split_it} or raise \
                 --max-memory if the machine has more to give",
                characters(pipeline),
                p.period_s,
                size(need),
                size(limit as f64)
            ),
        ));
    }
    Err(pipeline.field_error(
        "walkers",
        format!(
            "is {}: with {} standers over a {} s period {part} needs about {} at peak \
             (stages 4 to 8 hold every walker's points over one period), more than the {} of \
             {source}; lower `walkers` (or `standers`, `period_s`),{split_it} or raise \
             --max-memory if the machine has more to give",
            p.walkers,
            p.standers,
            p.period_s,
            size(need),
            size(limit as f64)
        ),
    ))
}

/// Bytes as a person reads them.
fn size(bytes: f64) -> String {
    if bytes >= 1e9 {
        format!("{:.1} GB", bytes / 1e9)
    } else {
        format!("{:.0} MB", bytes / 1e6)
    }
}

/// `--max-memory`'s value: bytes, or a number with K, M, G or T (powers of 1024; `4G`, `512M`,
/// `1.5G`, an optional `B` or `iB` after the letter).
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (number, unit) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => (&t[..i], c.to_ascii_uppercase()),
        _ => (t, ' '),
    };
    let scale: f64 = match unit {
        ' ' => 1.0,
        'K' => 1024.0,
        'M' => 1024.0 * 1024.0,
        'G' => 1024.0 * 1024.0 * 1024.0,
        'T' => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => return Err(format!("`{text}`: expected a size such as 512M or 4G")),
    };
    match number.trim().parse::<f64>() {
        Ok(n) if n.is_finite() && n > 0.0 && n * scale < 1.8e19 => Ok((n * scale) as u64),
        _ => Err(format!(
            "`{text}`: expected a positive size such as 512M or 4G"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("2048"), Ok(2048));
        assert_eq!(parse_size("8kB"), Ok(8192));
        for bad in ["", "G", "-1G", "NaNG", "4X", "1e300T"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_estimate_is_within_half_of_the_measured_peaks() {
        let text = |walkers: u32, period: f64| {
            format!(
                "(scene: (meters_per_pixel: 1.0, layers: [(kind: Density, path: \"d.png\")]), \
                 walkers: {walkers}, standers: 0, patch_side_m: 8.0, period_s: {period}, \
                 radius_m: 0.3, seed: 1, output: \"out\")"
            )
        };
        for (walkers, period, measured) in [
            (1100, 20.0, 50e6),
            (4800, 20.0, 199e6),
            (95_000, 20.0, 3.0e9),
            (1100, 600.0, 313e6),
        ] {
            let file = PipelineFile::parse(std::path::Path::new("p.ron"), text(walkers, period))
                .unwrap_or_else(|e| panic!("{e}"));
            let e = estimate(&file, Split::Whole, 8);
            assert!(
                e > 0.5 * measured && e < 1.7 * measured,
                "{walkers} walkers, {period} s: {e} for {measured}"
            );
        }
    }

    /// A pipeline of `walkers` over a 20 s period, its stage 3 in regions of `regions` patches.
    fn pipeline(walkers: u32, regions: Option<u32>) -> PipelineFile {
        let optimize = regions.map_or(String::new(), |r| {
            format!("optimize: (region_patches: Some({r})), ")
        });
        let text = format!(
            "(scene: (meters_per_pixel: 1.0, layers: [(kind: Density, path: \"d.png\")]), \
             walkers: {walkers}, standers: 0, patch_side_m: 8.0, period_s: 20.0, \
             radius_m: 0.3, seed: 1, {optimize}output: \"out\")"
        );
        PipelineFile::parse(std::path::Path::new("p.ron"), text).unwrap_or_else(|e| panic!("{e}"))
    }

    /// A shard or a gather is sized by its part, never below what it was measured to take,
    /// and well under the whole build (the million's: 35 GB).
    #[test]
    fn a_split_build_is_sized_by_its_part() {
        let shard = |i, n| Split::Shard(crowd_core::Shard::new(i, n).unwrap());
        // painting is one region; the million, regions of 16 patches.
        for (walkers, split, measured) in [
            (95_000, shard(0, 4), 599e6),
            (95_000, shard(7, 8), 599e6),
            (1_016_000, shard(3, 8), 693e6),
            (95_000, Split::Gather, 1.17e9),
            (1_016_000, Split::Gather, 1.36e9),
        ] {
            let f = pipeline(walkers, (walkers > 100_000).then_some(16));

            let e = estimate(&f, split, 8);
            assert!(
                e >= measured && e < 1.4 * measured,
                "{walkers} walkers, {split:?}: {e} for {measured}"
            );
            assert!(
                e < 0.5 * estimate(&f, Split::Whole, 8),
                "{walkers} walkers, {split:?}"
            );
        }
        // The million's shards and gather fit a machine of 8 GB; the whole build does not.
        let million = pipeline(1_016_000, Some(16));
        let limit = Some(8_000_000_000);
        assert!(check(&million, (shard(0, 8), 8), limit).is_ok());
        assert!(check(&million, (Split::Gather, 8), limit).is_ok());
        let refused = check(&million, (Split::Whole, 8), limit)
            .unwrap_err()
            .to_string();
        assert!(
            refused.contains("the build needs about") && refused.contains("into shards"),
            "{refused}"
        );
        // Too little for a shard: more shards; for the gather, which holds its whole world's
        // check, shards are no advice.
        let tiny = Some(100_000_000);
        let refused = check(&million, (shard(0, 8), 8), tiny)
            .unwrap_err()
            .to_string();
        assert!(
            refused.contains("shard 0/8 needs") && refused.contains("more shards"),
            "{refused}"
        );
        let refused = check(&million, (Split::Gather, 8), tiny)
            .unwrap_err()
            .to_string();
        assert!(
            refused.contains("the gather needs") && !refused.contains("shards"),
            "{refused}"
        );
    }

    /// A build that stops early is sized by the stages it runs: the million's stages 1-2, 3
    /// and 4 whole, and a shard's regions step, fit a machine of 4 GB (each measured at 0.3-1.2
    /// GB); its whole build, or any that goes past stage 4 in one process, does not.
    #[test]
    fn a_build_that_stops_early_is_sized_by_its_last_stage() {
        let million = pipeline(1_016_000, Some(16));
        let limit = Some(4_000_000_000);
        let regions = Split::Shard(crowd_core::Shard::new(0, 8).unwrap());
        for (split, last, measured) in [
            (Split::Whole, 1, 43e6),
            (Split::Whole, 2, 331e6),
            (Split::Whole, 3, 912e6),
            (regions, 3, 333e6),
            (Split::Whole, 4, 1.23e9),
        ] {
            let e = estimate(&million, split, last);
            assert!(
                e >= measured,
                "{split:?} to stage {last}: {e} for {measured}"
            );
            assert!(
                check(&million, (split, last), limit).is_ok(),
                "{split:?}, {last}"
            );
        }
        for last in [5, 8] {
            assert!(
                check(&million, (Split::Whole, last), limit).is_err(),
                "{last}"
            );
        }
        // painting, one region: its stage 3 solves the world at once.
        let painting = pipeline(95_000, None);
        let e = estimate(&painting, Split::Whole, 3);
        assert!((598e6..1.4 * 598e6).contains(&e), "{e}");
    }
}
