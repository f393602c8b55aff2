//! A build split over processes (`crowd build --shard I/N`, then `--gather`): the parts put
//! together are the bytes one process writes, and a missing or stale part is refused.

use crate::util::*;
use std::path::Path;

/// Runs shards `0/n .. n-1/n` of `pipeline` as separate processes, `at_once` at a time, each
/// in its own folder under `dir` (as a job runner would), and copies every shard's files into
/// `gathered/shards`.
fn run_shards(pipeline: &Path, dir: &Path, n: u32, at_once: u32, gathered: &Path) {
    run_step(pipeline, dir, (n, at_once), &[]);
    for i in 0..n {
        copy_files(
            &shard_folder(dir, i).join("shards"),
            &gathered.join("shards"),
        );
    }
}

fn shard_folder(dir: &Path, i: u32) -> std::path::PathBuf {
    dir.join(format!("shard-{i}"))
}

/// `crowd build --shard I/N` with `args`, for every I, `at_once` processes at a time, each in
/// its own folder under `dir`; what each said.
fn run_step(pipeline: &Path, dir: &Path, (n, at_once): (u32, u32), args: &[&str]) -> Vec<String> {
    let mut said = Vec::new();
    for batch in (0..n).collect::<Vec<_>>().chunks(at_once as usize) {
        let running: Vec<_> = batch
            .iter()
            .map(|&i| {
                std::process::Command::new(env!("CARGO_BIN_EXE_crowd"))
                    .args(["build", "--pipeline", s(pipeline), "--output"])
                    .arg(shard_folder(dir, i))
                    .args(["--shard", &format!("{i}/{n}")])
                    .args(args)
                    .stdout(std::process::Stdio::null())
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .expect("crowd runs")
            })
            .collect();
        for (child, i) in running.into_iter().zip(batch) {
            let out = child.wait_with_output().expect("crowd runs");
            let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
            assert!(out.status.success(), "shard {i}/{n}: {stderr}");
            said.push(stderr);
        }
    }
    said
}

/// Every file `whole` has (but its times: `timings.ron`, `report.md`), with the same bytes.
fn assert_same_files(whole: &Path, gathered: &Path, name: &str) {
    let files = snapshot(whole);
    assert!(files.len() > 10, "{name}: {} files", files.len());
    for (file, bytes) in files {
        let other = std::fs::read(gathered.join(&file))
            .unwrap_or_else(|e| panic!("{name}: {file} not gathered: {e}"));
        assert!(
            other == bytes,
            "{name}: {file} differs from the one-process build"
        );
    }
}

/// Four shards run as separate processes, two at a time, then gathered, write the same bytes
/// as the one-process build of `city` and of `ring`.
#[test]
fn four_shards_gathered_write_what_one_process_writes() {
    for name in ["city", "ring"] {
        let whole = scene(name);
        let pipeline = scene_pipeline(name);
        let dir = tempfile::tempdir().unwrap();
        let gathered = dir.path().join("gathered");
        run_shards(&pipeline, dir.path(), 4, 2, &gathered);
        let shard_files = std::fs::read_dir(gathered.join("shards")).unwrap().count();
        assert_eq!(
            shard_files, 28,
            "{name}: four shards, a .ron and a .bin of stages 4, 5 and 6 each, and a check memo"
        );
        // A share of the check lost on the way (cut short) is only work the gather does.
        let damaged = name == "ring";
        if damaged {
            let memo = gathered.join("shards/check-1-of-4.memo");
            let bytes = std::fs::read(&memo).unwrap();
            std::fs::write(&memo, &bytes[..bytes.len() / 2]).unwrap();
        }
        let said = crowd_ok(&[
            "build",
            "--pipeline",
            s(&pipeline),
            "--output",
            s(&gathered),
            "--gather",
        ]);
        let said = String::from_utf8_lossy(&said.stderr);
        for stage in ["collide", "smooth"] {
            assert!(said.contains(&format!("{stage}: built")), "{name}: {said}");
        }
        // The shards judged their patches of the check: the gather, only the pairs along
        // their edges (and the damaged part's patches).
        let (own, pairs) = (
            judged_again(&said, "patches"),
            judged_again(&said, "their pairs"),
        );
        assert_eq!(own.1, pairs.1, "{name}: {said}");
        if damaged {
            assert!(own.0 > own.1 / 8 && own.0 < own.1 / 2, "{name}: {own:?}");
        } else {
            assert_eq!(own.0, 0, "{name}: {said}");
            assert!(pairs.0 > 0 && pairs.0 < pairs.1 / 4, "{name}: {pairs:?}");
        }
        assert_same_files(whole, &gathered, name);
    }
}

/// "WHAT X of Y" in a check's "judged again: ..." line, as (X, Y).
fn judged_again(said: &str, what: &str) -> (usize, usize) {
    let line = said
        .lines()
        .find(|l| l.contains("judged again:"))
        .unwrap_or_else(|| panic!("no check line judged again: {said}"));
    let at = line.find(&format!("{what} ")).expect(what) + what.len() + 1;
    let words: Vec<&str> = line[at..].split_whitespace().take(3).collect();
    let number = |w: &str| w.trim_end_matches([',', ')']).parse::<usize>().unwrap();
    (number(words[0]), number(words[2]))
}

/// `city` read in regions of 8 patches (the million's way: stage 3 by region).
fn city_in_regions(dir: &Path) -> std::path::PathBuf {
    let layers = format!("{}/", s(&shared_scenes().join("city")));
    let text = std::fs::read_to_string(scene_pipeline("city")).unwrap();
    let text = text
        .replace("../../../shared/scenes/city/", &layers)
        .replace(
            "    output:",
            "    optimize: (region_patches: Some(8)),\n    output:",
        );
    assert!(text.contains("region_patches") && text.contains(&layers));
    let path = dir.join("city-regions.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// How many regions of how many a build's stage 3 said it optimised.
fn regions_optimised(said: &str) -> (u32, u32) {
    let line = said
        .lines()
        .find(|l| l.contains("optimize: built"))
        .expect(said);
    let before = line.split(" regions optimised").next().expect(line);
    let mut words = before.rsplit(' ');
    let of = words.next().unwrap().parse().expect(line);
    let done = words.nth(1).unwrap().parse().expect(line);
    (done, of)
}

/// Stage 3 split too (`--shard I/N --until optimize`): the shards solve the regions between
/// them, each region once; then no shard, nor the gather, solves any region, and the gather
/// writes the bytes one process writes.
#[test]
fn regions_solved_by_the_shards_are_solved_by_none_after_them() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = city_in_regions(dir.path());
    let whole = dir.path().join("whole");
    let said = crowd_ok(&["build", "--pipeline", s(&pipeline), "--output", s(&whole)]);
    let (solved, regions) = regions_optimised(&String::from_utf8_lossy(&said.stderr));
    assert!(regions >= 8 && solved == regions, "{solved} of {regions}");
    // Step 1: each of 4 shards its run of the regions, two at a time.
    let said = run_step(&pipeline, dir.path(), (4, 2), &["--until", "optimize"]);
    let mut next = 0;
    for (i, said) in said.iter().enumerate() {
        let line = said
            .lines()
            .find(|l| l.contains("optimize: built"))
            .expect(said);
        let run = line
            .split("(regions ")
            .nth(1)
            .and_then(|r| r.split(' ').next());
        let (from, to) = run.and_then(|r| r.split_once("..")).expect(line);
        assert_eq!(from.parse::<u32>().unwrap(), next, "shard {i}: {line}");
        next = to.parse().unwrap();
        assert!(line.contains(&format!("of {regions}:")), "{line}");
        assert!(
            !shard_folder(dir.path(), i as u32)
                .join("patterns.ron")
                .exists(),
            "shard {i} made no whole stage 3"
        );
    }
    assert_eq!(next, regions, "every region dealt once");
    // Step 2: every shard holds every region part, and solves nothing.
    let gathered = dir.path().join("gathered");
    for i in 0..4 {
        for into in [shard_folder(dir.path(), i), gathered.clone()] {
            for j in 0..4 {
                let name = format!("optimize-{j}-of-4");
                for ext in ["ron", "bin"] {
                    let file = format!("shards/{name}.{ext}");
                    let from = shard_folder(dir.path(), j).join(&file);
                    std::fs::create_dir_all(into.join("shards")).unwrap();
                    if from != into.join(&file) {
                        std::fs::copy(&from, into.join(&file)).unwrap();
                    }
                }
            }
        }
    }
    for said in run_step(&pipeline, dir.path(), (4, 2), &[]) {
        assert_eq!(regions_optimised(&said), (0, regions), "{said}");
        assert!(said.contains("in 4 shard parts"), "{said}");
    }
    for i in 0..4 {
        copy_files(
            &shard_folder(dir.path(), i).join("shards"),
            &gathered.join("shards"),
        );
    }
    // The gather makes stages 1-4 itself (no shard left it them), taking every region.
    let said = crowd_ok(&[
        "build",
        "--pipeline",
        s(&pipeline),
        "--output",
        s(&gathered),
        "--gather",
    ]);
    assert_eq!(
        regions_optimised(&String::from_utf8_lossy(&said.stderr)),
        (0, regions)
    );
    assert_same_files(&whole, &gathered, "city in regions");
    // A region part of other settings is refused, by name, before anything is written.
    let other = dir.path().join("other.ron");
    let text = std::fs::read_to_string(&pipeline).unwrap();
    std::fs::write(&other, text.replace("seed: 1,", "seed: 2,")).unwrap();
    let stale = dir.path().join("stale");
    std::fs::create_dir_all(stale.join("shards")).unwrap();
    copy_files(&gathered.join("shards"), &stale.join("shards"));
    let stderr = crowd_err(&[
        "build",
        "--pipeline",
        s(&other),
        "--output",
        s(&stale),
        "--gather",
    ]);
    assert!(
        stderr.contains("optimize-0-of-4.ron") && stderr.contains("was made for other inputs"),
        "{stderr}"
    );
    assert!(
        !stale.join("graph.ron").exists(),
        "a refused gather writes nothing"
    );
}

/// Gathering refuses, naming the file, a missing shard and a shard made from other settings,
/// and writes no file when it does.
#[test]
fn gathering_refuses_a_missing_or_stale_shard() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let painting = crowd_paintings::random(3, crowd_paintings::Limits { max_patches: 6 });
    let pipeline = painting.write(&scene).unwrap();
    let gathered = dir.path().join("gathered");
    run_shards(&pipeline, dir.path(), 3, 3, &gathered);
    let gathered_s = s(&gathered).to_string();
    let gather = [
        "build",
        "--pipeline",
        s(&pipeline),
        "--output",
        &gathered_s,
        "--gather",
    ];
    // A refused gather exits 1 (no panic), names the part and what is wrong with it, and
    // writes nothing.
    let refused = |part: &str, says: &str| {
        let stderr = crowd_err(&gather);
        assert!(stderr.contains(part) && stderr.contains(says), "{stderr}");
        for made in ["graph.ron", "collided.ron"] {
            assert!(!gathered.join(made).exists(), "{made} written: {stderr}");
        }
    };
    // One part missing: stage 5's of shard 1, then stage 6's of shard 0 (stage 5 gathers,
    // stage 6 refuses).
    for part in ["collide-1-of-3.ron", "smooth-0-of-3.ron"] {
        let path = gathered.join("shards").join(part);
        let kept = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        refused(part, "is missing");
        std::fs::write(&path, kept).unwrap();
    }
    // A shard of another seed.
    let text = std::fs::read_to_string(&pipeline).unwrap();
    let other = scene.join("other.ron");
    std::fs::write(&other, text.replace("seed: 3,", "seed: 4,")).unwrap();
    assert_ne!(
        std::fs::read(&other).unwrap(),
        text.as_bytes(),
        "the seed changed"
    );
    let stale = dir.path().join("stale");
    crowd_ok(&[
        "build",
        "-q",
        "--pipeline",
        s(&other),
        "--output",
        s(&stale),
        "--shard",
        "2/3",
    ]);
    std::fs::copy(
        stale.join("shards/collide-2-of-3.ron"),
        gathered.join("shards/collide-2-of-3.ron"),
    )
    .unwrap();
    refused("collide-2-of-3.ron", "was made for other inputs");
}

/// `--shard` takes I/N with I < N, and says so otherwise; `--gather` without shard files
/// says how to make them, and leaves no folder behind.
#[test]
fn a_shard_is_named_i_of_n() {
    let pipeline = scene_pipeline("bands");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let stderr = crowd_err(&[
        "build",
        "--pipeline",
        s(&pipeline),
        "--output",
        s(&out),
        "--gather",
    ]);
    assert!(
        stderr.contains("holds no shard file") && stderr.contains("--shard I/N"),
        "{stderr}"
    );
    assert!(!out.exists(), "a refused gather leaves no folder");
    for bad in ["4/4", "1/0", "x/2", "3"] {
        let out = crowd(&["build", "--pipeline", s(&pipeline), "--shard", bad]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {stderr}");
        assert!(stderr.contains("expected I/N"), "{bad}: {stderr}");
    }
    // A shard stops after its regions (stage 3) or its part of stage 6, nowhere else.
    let args = ["build", "--pipeline", s(&pipeline), "--output", s(&out)];
    let out_of_place = crowd(&[&args[..], &["--shard", "1/4", "--until", "match"]].concat());
    let stderr = String::from_utf8_lossy(&out_of_place.stderr);
    assert_eq!(out_of_place.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--until optimize"), "{stderr}");
    assert!(!out.exists(), "a refused shard leaves no folder");
}

/// The job-runner examples of `deploy/` run as each runner runs them: shard 0 given by hand
/// (`SHARD_INDEX`, a CI matrix), shard 1 as a Kubernetes Indexed Job pod
/// (`JOB_COMPLETION_INDEX`), shard 2 as a Slurm array task (`slurm/shards.sbatch` with
/// `SLURM_ARRAY_TASK_ID`, three tasks here), each step of them; `gather.sh` then writes the
/// one-process bytes, making none of stages 1-3 again (shard 0 left them).
#[test]
fn the_deploy_scripts_shard_and_gather_as_each_job_runner_runs_them() {
    let name = "ring";
    let deploy = root().join("deploy");
    let dir = tempfile::tempdir().unwrap();
    let shared = dir.path().join("shared");
    let run = |script: &Path, vars: &[(&str, &str)]| {
        let out = std::process::Command::new("sh")
            .arg(script)
            .env("PIPELINE", scene_pipeline(name))
            .env("SHARDS", "3")
            .env("SHARED", &shared)
            .env("WORK", dir.path())
            .env("CROWD", env!("CARGO_BIN_EXE_crowd"))
            .env("DEPLOY", &deploy)
            .env_remove("SHARD_INDEX")
            .env_remove("JOB_COMPLETION_INDEX")
            .env_remove("SLURM_ARRAY_TASK_ID")
            .envs(vars.iter().copied())
            .output()
            .expect("sh runs");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let shard = deploy.join("shard.sh");
    let (code, stderr) = run(&shard, &[]);
    assert_eq!(code, Some(2), "no index: {stderr}");
    assert!(stderr.contains("no shard index"), "{stderr}");
    let early = dir.path().join("early");
    let (code, stderr) = run(&deploy.join("gather.sh"), &[("OUTPUT", s(&early))]);
    assert_eq!(code, Some(1), "a gather before any shard: {stderr}");
    assert!(stderr.contains("no shard files"), "{stderr}");
    assert!(!early.exists(), "a refused gather makes no folder");
    let (code, stderr) = run(&shard, &[("SHARD_INDEX", "0"), ("STEP", "all")]);
    assert_eq!(code, Some(2), "no such step: {stderr}");
    assert!(stderr.contains("STEP is regions or patches"), "{stderr}");
    // Each step as each runner runs it: the regions, then the patches.
    for (step, slurm) in [
        ("regions", "slurm/regions.sbatch"),
        ("patches", "slurm/shards.sbatch"),
    ] {
        for (script, var, index) in [
            (&shard, "SHARD_INDEX", "0"),
            (&shard, "JOB_COMPLETION_INDEX", "1"),
            (&deploy.join(slurm), "SLURM_ARRAY_TASK_ID", "2"),
        ] {
            let vars = [
                (var, index),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
                ("STEP", step),
            ];
            let (code, stderr) = run(script, &vars);
            assert_eq!(code, Some(0), "{step}: {var}={index}: {stderr}");
        }
    }
    let files = std::fs::read_dir(shared.join("shards")).unwrap().count();
    assert_eq!(
        files, 27,
        "three shards, a .ron and a .bin of stages 3-6 each and a check memo, no partial copies"
    );
    // The patches step took every region from the regions step.
    for j in 0..3 {
        let part = dir
            .path()
            .join(format!("shard-1/shards/optimize-{j}-of-3.ron"));
        assert!(part.exists(), "{} not taken", part.display());
    }
    let gathered = dir.path().join("gathered");
    let output = gathered.to_str().unwrap();
    let (code, stderr) = run(&deploy.join("gather.sh"), &[("OUTPUT", output)]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_same_files(scene(name), &gathered, name);
    // Stages 1-3 came from shard 0: the gather ran none of them, and gathered stage 4.
    let timings = std::fs::read_to_string(gathered.join("timings.ron")).unwrap();
    for stage in ["merge", "graph", "optimize"] {
        assert!(
            !timings.contains(&format!("\"{stage}\"")),
            "{stage} ran: {timings}"
        );
    }
    for stage in ["match", "collide"] {
        assert!(timings.contains(&format!("\"{stage}\"")), "{timings}");
    }
}

/// A regions step with fewer regions than shards says which shards have nothing to solve and
/// which setting splits stage 3 further, instead of leaving it to be found in the timings.
#[test]
fn a_world_of_fewer_regions_than_shards_says_how_to_split_it() {
    let pipeline = scene_pipeline("bands");
    let dir = tempfile::tempdir().unwrap();
    let said = crowd_ok(&[
        "build",
        "--pipeline",
        s(&pipeline),
        "--output",
        s(&dir.path().join("one")),
        "--shard",
        "1/4",
        "--until",
        "optimize",
    ]);
    let said = String::from_utf8_lossy(&said.stderr);
    assert!(
        said.contains("one region for 4 shards (no `optimize.region_patches`): only shard 0"),
        "{said}"
    );
}
