//! Unit tests of the evaluation: scoring, aggregates, the text table and sets.

use super::*;

fn row(subject: &str, errors: &[(&str, Option<f64>)]) -> EvalRow {
    EvalRow {
        subject: subject.into(),
        measurements: errors
            .iter()
            .map(|&(name, e)| MeasurementCompare {
                name: name.into(),
                true_mm: 800.0,
                fitted_mm: e.map(|e| 800.0 + e),
                error_mm: e,
                pm_mm: Some(8.0),
            })
            .collect(),
        surface: None,
        mask_iou: BTreeMap::new(),
        landmarks: LandmarkErrors::default(),
        body_landmarks: LandmarkErrors::default(),
        timings_ms: BTreeMap::new(),
        profile: Vec::new(),
        settled_step_mm: BTreeMap::new(),
        frames: None,
        turn: TurnCompare {
            true_deg: 0.0,
            read_deg: None,
        },
    }
}

#[test]
fn sets_side_by_side_shows_each_sets_mae_bias_and_worst() {
    let a = EvalTable {
        rows: vec![
            row(
                "subject_00",
                &[("chest_girth", Some(4.0)), ("hip_girth", Some(-2.0))],
            ),
            row(
                "subject_01",
                &[("chest_girth", Some(-10.0)), ("hip_girth", Some(6.0))],
            ),
        ],
        failures: vec!["subject_02: no frame".into()],
    };
    let b = EvalTable {
        rows: vec![row("subject_00", &[("chest_girth", Some(30.0))])],
        failures: Vec::new(),
    };
    let t = sets_side_by_side(&[("library".into(), a), ("ansur".into(), b)]);
    let chest = t
        .lines()
        .find(|l| l.starts_with("chest_girth"))
        .expect("chest row");
    assert!(chest.contains("7.0 / -3.0 / -10.0"), "{chest}");
    assert!(chest.contains("30.0 / +30.0 / +30.0"), "{chest}");
    let hip = t
        .lines()
        .find(|l| l.starts_with("hip_girth"))
        .expect("hip row");
    assert!(
        hip.contains("4.0 / +2.0 / +6.0") && hip.trim_end().ends_with('-'),
        "{hip}"
    );
    // Each chest row is given ±8: 4 mm is within it, -10 mm is not.
    let cover = t
        .split("within ± / median ±")
        .nth(1)
        .and_then(|b| b.lines().find(|l| l.starts_with("chest_girth")))
        .expect("cover row");
    assert!(
        cover.contains("1/2 / 8.0") && cover.contains("0/1 / 8.0"),
        "{cover}"
    );
    let fitted = t
        .lines()
        .find(|l| l.starts_with("subjects"))
        .expect("count row");
    assert!(
        fitted.contains("2 of 3") && fitted.contains("1 of 1"),
        "{fitted}"
    );
}

#[test]
fn a_set_lists_the_recordings_with_truth_and_bad_specs_are_said() {
    let dir = std::env::temp_dir().join(format!("fitstation_evalset_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for d in [
        "subject_01",
        "subject_01.truth",
        "subject_00",
        "subject_00.truth",
        "notes",
    ] {
        std::fs::create_dir_all(dir.join(d)).expect("mkdir");
    }
    let set = parse_set(&format!("lib={}", dir.display())).expect("set");
    assert_eq!(set.name, "lib");
    assert_eq!(
        set.recordings,
        vec![dir.join("subject_00"), dir.join("subject_01")]
    );
    assert!(parse_set("nodir").is_err());
    assert!(parse_set(&format!("empty={}", dir.join("notes").display())).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn worst_girth_is_the_largest_girth_error_of_the_set() {
    let table = EvalTable {
        rows: vec![
            row(
                "a",
                &[
                    ("chest_girth", Some(4.0)),
                    ("waist_girth", Some(-9.5)),
                    // Not tape girths: never the worst girth.
                    ("stature", Some(40.0)),
                    ("hip_girth_max", Some(-30.0)),
                ],
            ),
            row(
                "b",
                &[
                    ("thigh_girth_left", Some(9.0)),
                    ("hip_girth", None),
                    ("thigh_girth_right", Some(-12.25)),
                ],
            ),
        ],
        failures: Vec::new(),
    };
    let w = table.worst_girth().expect("a worst girth");
    assert_eq!(
        (w.name.as_str(), w.subject.as_str(), w.error_mm),
        ("thigh_girth_right", "b", -12.25)
    );
    assert_eq!(w.fitted_mm, 800.0 - 12.25);
    let text = table.to_text();
    assert!(
        text.contains(
            "worst single girth error of the set: -12.2 mm (thigh_girth_right, subject b"
        ),
        "{text}"
    );
    let html = super::html::report(&table, &[]);
    assert!(
        html.contains("thigh_girth_right, subject b"),
        "no worst girth in the HTML"
    );
    assert!(EvalTable::default().worst_girth().is_none());
}

#[test]
fn truth_landmark_names_map_to_the_stations() {
    assert_eq!(station_landmark_name("left_armpit"), "armpit_left");
    assert_eq!(station_landmark_name("right_acromion"), "acromion_right");
    assert_eq!(station_landmark_name("crotch"), "crotch");
    assert_eq!(station_landmark_name("head_top"), "head_top");
    // Every such name is one the station writes.
    use crate::landmarks::LandmarkName::*;
    for (n, l) in [
        ("left_armpit", ArmpitLeft),
        ("right_armpit", ArmpitRight),
        ("left_acromion", AcromionLeft),
        ("right_acromion", AcromionRight),
    ] {
        assert_eq!(station_landmark_name(n), l.as_str());
    }
}

/// The turn the fit read is scored against the truth's: read on how many, its error, the
/// worst subject and the sign of the clear turns; the text table says so per subject.
#[test]
fn turns_read_are_scored_against_the_truths() {
    let with = |name: &str, read: Option<f64>, truth: f64| {
        let mut r = row(name, &[("chest_girth", Some(1.0))]);
        r.turn = TurnCompare {
            true_deg: truth,
            read_deg: read,
        };
        r
    };
    let table = EvalTable {
        rows: vec![
            with("a", Some(2.5), 2.0),
            with("b", Some(-3.5), -2.0),
            with("c", None, 4.0),
            with("d", Some(0.3), 0.5),
        ],
        failures: Vec::new(),
    };
    let t = table.turn_summary().expect("rows");
    assert_eq!((t.subjects, t.read), (4, 3));
    assert!((t.mean_error_deg - (0.5 - 1.5 - 0.2) / 3.0).abs() < 1e-12);
    assert!((t.mean_abs_error_deg - (0.5 + 1.5 + 0.2) / 3.0).abs() < 1e-12);
    assert_eq!((t.worst_error_deg, t.worst_subject.as_str()), (-1.5, "b"));
    assert_eq!((t.turned, t.sign_right), (2, 2));
    let text = table.to_text();
    assert!(
        text.contains("+2.5/+2.0") && text.contains("-/+4.0"),
        "{text}"
    );
    assert!(
        text.contains("turn on the mark read on 3 of 4 subjects"),
        "{text}"
    );
    assert_eq!(EvalTable::default().turn_summary(), None);
}

#[test]
fn the_maes_interval_spans_what_another_draw_of_subjects_would_give() {
    // Errors 0, 10, 20, ... 230 mm: MAE 115. Another draw of 24 from them moves the MAE
    // by about its standard error, 69 / sqrt(24) = 14 mm: the 90 % interval is about
    // 115 -/+ 1.645 x 14.
    let errors: Vec<f64> = (0..24).map(|i| 10.0 * i as f64).collect();
    let (lo, hi) = table::mae_interval(&errors).expect("24 subjects");
    assert!(lo < 115.0 && 115.0 < hi, "{lo} {hi}");
    assert!((hi - lo - 2.0 * 1.645 * 14.1).abs() < 6.0, "{lo} {hi}");
    // Signs do not matter, order does not matter, and the same errors give the same
    // interval.
    let mut flipped: Vec<f64> = errors.iter().rev().map(|e| -e).collect();
    flipped.rotate_left(5);
    let (lo2, hi2) = table::mae_interval(&flipped).expect("24 subjects");
    assert!(
        (lo2 - lo).abs() < 3.0 && (hi2 - hi).abs() < 3.0,
        "{lo2} {hi2}"
    );
    assert_eq!(table::mae_interval(&errors), Some((lo, hi)));
    // All alike: no spread. Too few subjects: no interval.
    assert_eq!(table::mae_interval(&[7.0; 12]), Some((7.0, 7.0)));
    assert_eq!(table::mae_interval(&[1.0, 2.0, 3.0, 4.0]), None);
    // Quadrupling the subjects halves the interval.
    let many: Vec<f64> = (0..96).map(|i| 10.0 * (i % 24) as f64).collect();
    let (lo4, hi4) = table::mae_interval(&many).expect("96 subjects");
    let ratio = (hi4 - lo4) / (hi - lo);
    assert!((ratio - 0.5).abs() < 0.12, "{ratio}");
}

#[test]
fn the_tables_give_each_maes_interval() {
    let rows: Vec<EvalRow> = (0..6)
        .map(|i| {
            row(
                &format!("subject_{i:02}"),
                &[("chest_girth", Some(2.0 * i as f64))],
            )
        })
        .collect();
    let t = EvalTable {
        rows,
        failures: Vec::new(),
    };
    let (lo, hi) = t.summary()[0].mae_interval_mm.expect("6 subjects");
    assert!(lo < 5.0 && 5.0 < hi, "{lo} {hi}");
    let cell = format!("{lo:.1}-{hi:.1}");
    assert!(t.to_text().contains(&cell), "{}", t.to_text());
    let side = sets_side_by_side(&[("ansur".into(), t)]);
    let block = side
        .split("MAE 90 % interval")
        .nth(1)
        .expect("the interval block");
    let chest = block
        .lines()
        .find(|l| l.starts_with("chest_girth"))
        .expect("chest row");
    assert!(chest.contains(&cell), "{chest}");
}
