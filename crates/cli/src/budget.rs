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

use crowd_core::config::{LayerKind, People, PipelineFile};

/// Memory of a build whatever its size, bytes: the binary, the maps, the graph.
const BASE: f64 = 40e6;
/// Peak bytes per walker (or stander) at a 20 s period.
const PER_WALKER: f64 = 35e3;
/// How the peak grows with the period: (period / 20 s) to this power.
const PERIOD_POWER: f64 = 0.6;

/// The estimated peak memory of building `pipeline`, bytes.
pub fn estimate(pipeline: &PipelineFile) -> f64 {
    let p = &pipeline.pipeline;
    BASE + characters(pipeline) * PER_WALKER * (p.period_s / 20.0).powf(PERIOD_POWER)
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

/// Refuses `pipeline` when its estimated peak passes `limit` bytes (`--max-memory`, else the
/// machine's memory; no limit where neither is known).
pub fn check(pipeline: &PipelineFile, limit: Option<u64>) -> crowd_core::Result<()> {
    let (limit, source) = match limit {
        Some(l) => (l, "--max-memory"),
        None => match machine_memory() {
            Some(l) => (l, "this machine's memory"),
            None => return Ok(()),
        },
    };
    let need = estimate(pipeline);
    if need <= limit as f64 {
        return Ok(());
    }
    let p = &pipeline.pipeline;
    if let People::PerSquareMetre { .. } = p.people {
        return Err(pipeline.field_error(
            "people",
            format!(
                "asks for about {:.0} characters as the layers are painted, over a {} s \
                 period: the build could need about {} at peak, more than the {} of \
                 {source}; lower the densities (or `period_s`), or raise --max-memory if the \
                 machine has more to give",
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
            "is {}: with {} standers over a {} s period the build needs about {} at peak \
             (stages 4 to 8 hold every walker's points over one period), more than the {} of \
             {source}; lower `walkers` (or `standers`, `period_s`), or raise --max-memory if \
             the machine has more to give",
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
            let e = estimate(&file);
            assert!(
                e > 0.5 * measured && e < 1.7 * measured,
                "{walkers} walkers, {period} s: {e} for {measured}"
            );
        }
    }
}
