//! Plays a library for a number of frames at 60 (or FPS) frames a second, whole world in view:
//! a driver for profilers (`valgrind --tool=callgrind`), which criterion's harness would swamp.
//! `cargo run --release -p crowd-runtime --example frames -- LIBRARY [FRAMES [FPS]]`

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or("usage: frames LIBRARY [FRAMES [FPS]]")?;
    let frames: u32 = args.next().map_or(Ok(600), |f| f.parse())?;
    let fps: f64 = args.next().map_or(Ok(60.0), |f| f.parse())?;
    let lib = crowd_runtime::Library::from_bytes(&std::fs::read(&path)?)?;
    let side = lib.world.patch_side_m;
    let view = [
        0.0,
        0.0,
        lib.world.cols as f32 * side,
        lib.world.rows as f32 * side,
    ];
    let mut sampler = crowd_runtime::Sampler::new(&lib);
    let mut out = Vec::new();
    sampler.sample(0.0, view, &mut out);
    let start = std::time::Instant::now();
    let mut seen = 0;
    for f in 1..=frames {
        sampler.sample(f64::from(f) / fps, view, &mut out);
        seen += out.len();
    }
    let per = start.elapsed().as_secs_f64() / f64::from(frames);
    println!(
        "{frames} frames, {:.3} ms a frame, {seen} samples",
        per * 1e3
    );
    Ok(())
}
