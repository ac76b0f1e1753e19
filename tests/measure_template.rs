//! The station's body template (`templates/makehuman-adult.obj`, committed by the body
//! module) measures as a plausible adult. Skipped, loudly, in a tree without it.

use fitstation::measure::{cli, measure};
use fitstation::mesh::io::read_mesh;
use std::path::Path;

#[test]
fn template_measures_as_a_plausible_adult() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("templates/makehuman-adult.obj");
    if !path.exists() {
        println!("SKIPPED: {} not in this tree", path.display());
        return;
    }
    let mesh = read_mesh(&path).expect("template OBJ");
    let m = measure(&mesh).expect("the template measures");
    println!("{}", cli::table(&m));
    let within = |what: &str, v: f64, lo: f64, hi: f64| {
        assert!(
            v >= lo && v <= hi,
            "{what} = {v:.1} mm outside [{lo}, {hi}]"
        );
    };
    within("stature", m.stature_mm, 1600.0, 1800.0);
    within("chest", m.chest_girth_mm, 850.0, 1100.0);
    within("waist", m.waist_girth_mm, 650.0, 950.0);
    within("hip", m.hip_girth_mm, 850.0, 1100.0);
    within("thigh left", m.thigh_girth_left_mm, 450.0, 650.0);
    within("thigh right", m.thigh_girth_right_mm, 450.0, 650.0);
    let asym = (m.thigh_girth_left_mm - m.thigh_girth_right_mm).abs() / m.thigh_girth_right_mm;
    assert!(asym < 0.02, "thighs differ by {:.2} %", asym * 100.0);
    // Soles on the floor: the stature is the top of the head.
    let top = mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        (top * 1e3 - m.stature_mm).abs() < 5.0,
        "soles not on y = 0?"
    );
}
