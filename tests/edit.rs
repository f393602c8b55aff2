//! `crowd edit --experiment NAME`: the paper's experiments run end to end and write their
//! files; bad input is refused with a message naming what is wrong, before any file is written.

use crate::util::*;

#[test]
fn an_experiment_writes_its_table_pictures_and_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rv");
    crowd_ok(&[
        "edit",
        "--experiment",
        "rendez-vous",
        "--iterations",
        "3",
        "-q",
        "-o",
        out.to_str().unwrap(),
    ]);
    let csv = std::fs::read_to_string(out.join("iterations.csv")).unwrap();
    assert!(csv.starts_with("iteration,kind,step,cost"), "{csv}");
    assert_eq!(
        csv.lines().count(),
        1 + 1 + 3,
        "a header, the start and 3 iterations"
    );
    let result = std::fs::read_to_string(out.join("result.ron")).unwrap();
    assert!(result.contains("experiment: \"rendez-vous\""), "{result}");
    for picture in ["iterations.png", "trajectories.png"] {
        image::open(out.join(picture)).expect("a readable PNG");
    }
}

#[test]
fn bad_input_to_crowd_edit_names_what_is_wrong_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    let cases: [(&[&str], &str); 8] = [
        (
            &["--experiment", "density", "--iterations", "100000000"],
            "--iterations is 100000000; expected 1 to 10000",
        ),
        (
            &["--experiment", "density", "--r", "1e-300"],
            "the descent found no step that lowers the cost from the unedited crowd",
        ),
        (
            &["--experiment", "dance"],
            "unknown experiment `dance`; expected one of: rendez-vous",
        ),
        (
            &["--experiment", "rendez-vous", "--meet", "80,5"],
            "constraint `meet` asks for (80, 5) m, outside the world",
        ),
        (
            &["--experiment", "rendez-vous", "--meet-time", "45"],
            "constraint `meet` is at t = 45 s, outside the simulation (0 to 30 s)",
        ),
        (
            &["--experiment", "density", "--r", "0"],
            "constraint `area 1 at 7 s`'s R is 0; a covariance must be a finite number above zero",
        ),
        (
            &["--experiment", "letters", "--q", "-1"],
            "Q_u is -1; a covariance must be a finite number above zero",
        ),
        (
            &["--experiment", "flow", "--meet", "1,1"],
            "--meet / --meet-time applies only to the `rendez-vous` experiment, not `flow`",
        ),
    ];
    for (args, expected) in cases {
        let mut all = vec!["edit", "-o", o];
        all.extend_from_slice(args);
        let err = crowd_err(&all);
        assert!(err.contains(expected), "crowd {all:?}:\n{err}");
        assert!(!out.exists(), "crowd {all:?} wrote {}", out.display());
    }
}
