use super::{failure::*, inputs::*, prepare::*, run::*, tracked::*, types::*};
use crate::dataset::DropRecord;
use crate::pipeline::shelf::Shelf;
use crate::util::io::Spool;
use std::path::{Path, PathBuf};

#[test]
fn a_panic_in_a_run_becomes_its_failed_row() {
    let cfg = crate::test_support::default_config();
    let dir = tempfile::tempdir().unwrap();
    let cine = dir.path().join("drop.cine");
    std::fs::write(&cine, b"").unwrap();
    let runs = runs_from_inputs(std::slice::from_ref(&cine), Some(3.0), &cfg).unwrap();
    let o = caught(&runs[0], || -> Result<RunOutcome, String> {
        let lo = 2.0_f64;
        Ok(RunOutcome {
            record: DropRecord::failed("never", 1.0, format!("{}", 1.0_f64.clamp(lo, 1.0))),
            track_csv: Spool::new(0),
            track_rows: 0,
            overlay: None,
            frame_overlays: Vec::new(),
            impact: None,
            scene: None,
            seconds: 0.0,
            notes: Vec::new(),
        })
    })
    .unwrap_or_else(|reason| failed_outcome(&runs[0], &cfg, reason, None));
    assert_eq!(o.record.status, crate::dataset::DropStatus::Failed);
    assert_eq!(o.record.run, "drop");
    assert!(
        o.record
            .reason
            .starts_with(&format!("{}: internal error", cine.display()))
            && o.record.reason.contains("min > max"),
        "{}",
        o.record.reason
    );
}

/// What a [`Tracked`] holds, as text: the same text is the same bits
/// (`{:?}` prints the shortest decimal that reads back as the same f64).
fn tracked_text(t: &Tracked) -> String {
    format!(
        "{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{}",
        t.meta,
        t.tr,
        t.curvature,
        t.bounded,
        t.source.meta(),
        t.surface_name
    )
}

#[test]
fn a_track_kept_from_reading_the_scenes_is_the_track_made_again() {
    let cfg = crate::test_support::default_config();
    let mut runs = crate::dataset::manifest::read_manifest(Path::new("fixtures/runs.csv")).unwrap();
    let mut missing = runs[0].clone();
    missing.run = "missing".into();
    missing.path = PathBuf::from("fixtures/no-such-run");
    runs.push(missing);
    let p = prepare(&runs, &cfg, &|_| None, &|_| {});
    for (i, run) in p.runs.iter().enumerate() {
        let kept = p.kept.take(i).expect("every run without a set-up is kept");
        assert!(p.kept.take(i).is_none(), "taken once");
        let again = track_run(run, &p.cfg);
        match (kept.restore(run, &p.cfg).expect("read back"), again) {
            (Ok(a), Ok(b)) => assert!(
                tracked_text(&a) == tracked_text(&b),
                "{}: the kept track differs",
                run.run
            ),
            (Err(a), Err(b)) => assert_eq!(a, b),
            (a, b) => panic!("{}: {:?} against {:?}", run.run, a.err(), b.err()),
        }
    }
    // Records in their own file (a long movie's) stay there and read
    // back the same.
    let shelf = Shelf::new().unwrap();
    let mut t = track_run(&p.runs[1], &p.cfg).unwrap();
    let expected = format!("{:?}", t.tr);
    let mut spilled = crate::util::records::Records::new(10);
    for r in t.tr.frames.iter() {
        spilled.push(r).unwrap();
    }
    spilled.flush().unwrap();
    assert!(spilled.spilled());
    t.tr.frames = spilled;
    let back = shelf.take(shelf.put(t.tr).unwrap()).unwrap();
    assert!(back.frames.spilled());
    assert!(
        format!("{back:?}") == expected,
        "a track with its records in a file"
    );
}

#[test]
fn runs_of_one_setup_are_grouped_in_order_and_the_rest_stand_alone() {
    let run = crate::test_support::run_spec;
    let runs = [
        run("a", Some("cam1")),
        run("b", None),
        run("c", Some("cam2")),
        run("d", Some("cam1")),
        run("e", None),
        run("f", Some("cam2")),
    ];
    assert_eq!(
        setups(&runs),
        vec![vec![0, 3], vec![1], vec![2, 5], vec![4]]
    );
}

#[test]
fn input_runs_get_unique_names_and_need_a_radius() {
    let cfg = crate::test_support::default_config();
    let dir = tempfile::tempdir().unwrap();
    let inputs = ["a", "b"].map(|d| {
        std::fs::create_dir(dir.path().join(d)).unwrap();
        let cine = dir.path().join(d).join("drop.cine");
        std::fs::write(&cine, b"").unwrap();
        cine
    });
    let runs = runs_from_inputs(&inputs, Some(3.0), &cfg).unwrap();
    assert_eq!(runs[0].run, "drop");
    assert_eq!(runs[1].run, "drop_2");
    let e = runs_from_inputs(&inputs, None, &cfg)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("--radius-mm") && e.contains("sphere.radius_mm"),
        "{e}"
    );
}

/// An INPUT that names nothing, or nothing that can be a run, is an
/// error naming it; what is inside an input is left to its run.
#[test]
fn inputs_that_are_not_there_or_cannot_be_runs_are_refused() {
    let cfg = crate::test_support::default_config();
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("R4.5mm_H12cm_01");
    std::fs::create_dir(&good).unwrap();
    let notes = dir.path().join("runs.csv");
    std::fs::write(&notes, b"run,path\n").unwrap();
    for (bad, says) in [
        (dir.path().join("R4.5mm_H12cm_01_typo"), "does not exist"),
        (dir.path().join("nowhere/drop.cine"), "does not exist"),
        (notes, "not a folder of frames"),
    ] {
        let e = runs_from_inputs(&[good.clone(), bad.clone()], Some(4.5), &cfg).unwrap_err();
        assert!(matches!(e, ProcessError::Input { .. }), "{e:?}");
        let e = e.to_string();
        assert!(e.starts_with(&format!("{}: {says}", bad.display())), "{e}");
    }
    // An empty folder or a cine that is not one is a run, to fail on its own.
    let broken = dir.path().join("broken.cine");
    std::fs::write(&broken, b"CI not a cine").unwrap();
    assert_eq!(
        runs_from_inputs(&[good, broken], Some(4.5), &cfg)
            .unwrap()
            .len(),
        2
    );
}
