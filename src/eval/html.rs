//! The self-contained HTML evaluation report: inline SVG charts and base64 PNG
//! thumbnails, no external assets.
//!
//! Charts: per measurement, each subject's signed error (fitted - true, mm) as a bar;
//! per subject, the true and fitted girth profiles (largest section's hull perimeter
//! against height); per subject and view, the fitted avatar's silhouette (rendered with
//! the synthetic renderer's rasteriser through the recording's calibration) over the
//! first frame with the subject, with the true silhouette's outline.

use super::{EvalRow, EvalTable, LandmarkSource};
use crate::camera::View;
use crate::mesh::TriMesh;
use crate::recording::Recording;
use crate::synth::raster::Rasterizer;
use std::fmt::Write as _;
use std::path::Path;

/// Height of the overlay thumbnails, pixels.
pub const THUMB_HEIGHT: u32 = 300;
/// Margin around the silhouettes in a thumbnail, fraction of their height.
const THUMB_MARGIN: f64 = 0.06;
const FITTED_TINT: [f32; 3] = [255.0, 60.0, 200.0];
const TRUE_OUTLINE: [u8; 3] = [40, 255, 60];

/// One overlay thumbnail.
#[derive(Debug, Clone)]
pub struct Thumb {
    pub view: String,
    pub png_base64: String,
}

/// Standard base64 (RFC 4648) of `data`.
pub fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        s.push(T[(n >> 18) as usize & 63] as char);
        s.push(T[(n >> 12) as usize & 63] as char);
        s.push(if c.len() > 1 {
            T[(n >> 6) as usize & 63] as char
        } else {
            '='
        });
        s.push(if c.len() > 2 {
            T[n as usize & 63] as char
        } else {
            '='
        });
    }
    s
}

/// Overlays of the avatar's silhouette on the first subject frame of each view.
///
/// # Errors
/// The recording or its truth cannot be read.
pub fn overlay_thumbnails(
    recording: &Path,
    truth_dir: &Path,
    avatar: &TriMesh,
) -> anyhow::Result<Vec<Thumb>> {
    let truth = crate::synth::load_truth(truth_dir)?;
    let k = truth
        .per_frame
        .iter()
        .find(|f| f.subject)
        .map(|f| f.index)
        .unwrap_or(truth.frames.empty);
    let mut rec = Recording::open(recording)?;
    let (front, side) = rec.frame_pair(k)?;
    let mut out = Vec::new();
    for (view, frame) in [(View::Front, front), (View::Side, side)] {
        let cam = *rec.calibration().camera(view);
        let mut r = Rasterizer::new(frame.width(), frame.height());
        r.draw_mesh(&cam, &avatar.positions, &avatar.triangles);
        let true_mask = image::open(
            truth_dir
                .join("masks")
                .join(view.name())
                .join(format!("{k:06}.png")),
        )
        .ok()
        .map(|m| m.to_luma8());
        let mut img = frame;
        let w = img.width();
        for (i, (px, covered)) in img.pixels_mut().zip(r.coverage()).enumerate() {
            if covered {
                for (v, tint) in px.0.iter_mut().zip(FITTED_TINT) {
                    *v = (0.55 * *v as f32 + 0.45 * tint) as u8;
                }
            }
            if let Some(m) = &true_mask {
                let (x, y) = (i as u32 % w, i as u32 / w);
                let on = |x: u32, y: u32| m.get_pixel_checked(x, y).is_some_and(|p| p.0[0] > 127);
                let here = on(x, y);
                let edge = here
                    && (!on(x.wrapping_sub(1), y)
                        || !on(x + 1, y)
                        || !on(x, y.wrapping_sub(1))
                        || !on(x, y + 1));
                if edge {
                    px.0 = TRUE_OUTLINE;
                }
            }
        }
        // Crop to both silhouettes with a margin, so the body fills the thumbnail.
        let (w, h) = (img.width(), img.height());
        let mut bb: Option<(u32, u32, u32, u32)> = None;
        for (i, covered) in r.coverage().enumerate() {
            let (x, y) = (i as u32 % w, i as u32 / w);
            let in_truth = true_mask
                .as_ref()
                .is_some_and(|m| m.get_pixel_checked(x, y).is_some_and(|p| p.0[0] > 127));
            if covered || in_truth {
                bb = Some(bb.map_or((x, y, x, y), |b| {
                    (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y))
                }));
            }
        }
        let (x0, y0, x1, y1) = bb.unwrap_or((0, 0, w - 1, h - 1));
        let m = ((y1 - y0) as f64 * THUMB_MARGIN) as u32;
        let (x0, y0) = (x0.saturating_sub(m), y0.saturating_sub(m));
        let (x1, y1) = ((x1 + m).min(w - 1), (y1 + m).min(h - 1));
        let crop = image::imageops::crop_imm(&img, x0, y0, x1 - x0 + 1, y1 - y0 + 1).to_image();
        let tw = (crop.width() as f64 * THUMB_HEIGHT as f64 / crop.height() as f64)
            .round()
            .max(1.0) as u32;
        let small = image::imageops::resize(
            &crop,
            tw,
            THUMB_HEIGHT,
            image::imageops::FilterType::Triangle,
        );
        let mut png = Vec::new();
        small.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
        out.push(Thumb {
            view: view.name().into(),
            png_base64: base64(&png),
        });
    }
    Ok(out)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Bars of each subject's signed error for one measurement.
fn error_chart(table: &EvalTable, name: &str) -> String {
    let rows: Vec<(&str, f64)> = table
        .rows
        .iter()
        .filter_map(|r| {
            r.measurements
                .iter()
                .find(|m| m.name == name)
                .and_then(|m| m.error_mm)
                .map(|e| (r.subject.as_str(), e))
        })
        .collect();
    let (w, h, pad) = (360.0, 180.0, 28.0);
    let lim = rows.iter().map(|r| r.1.abs()).fold(5.0f64, f64::max) * 1.1;
    let y0 = h / 2.0;
    let sy = (h / 2.0 - pad) / lim;
    let bw = ((w - 2.0 * pad) / rows.len().max(1) as f64).min(40.0);
    let mut s = format!("<svg width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" xmlns=\"http://www.w3.org/2000/svg\">");
    let _ = write!(
        s,
        "<text x=\"4\" y=\"14\" font-size=\"12\" font-weight=\"bold\">{}</text>",
        esc(name)
    );
    let _ = write!(
        s,
        "<text x=\"{}\" y=\"14\" font-size=\"10\" text-anchor=\"end\">±{lim:.0} mm</text>",
        w - 4.0
    );
    let _ = write!(
        s,
        "<line x1=\"{pad}\" x2=\"{}\" y1=\"{y0}\" y2=\"{y0}\" stroke=\"#444\"/>",
        w - pad
    );
    for (i, (subj, e)) in rows.iter().enumerate() {
        let x = pad + i as f64 * bw + 0.15 * bw;
        let (y, bh) = if *e >= 0.0 {
            (y0 - e * sy, e * sy)
        } else {
            (y0, -e * sy)
        };
        let col = if *e >= 0.0 { "#d9534f" } else { "#337ab7" };
        let _ = write!(
            s,
            "<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{col}\"><title>{}: {e:+.1} mm</title></rect>",
            0.7 * bw,
            bh.max(0.5),
            esc(subj)
        );
        let _ = write!(
            s,
            "<text x=\"{:.1}\" y=\"{}\" font-size=\"8\" text-anchor=\"middle\">{}</text>",
            x + 0.35 * bw,
            h - 4.0,
            esc(&subj
                .chars()
                .rev()
                .take(4)
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .collect::<String>())
        );
    }
    s.push_str("</svg>");
    s
}

/// True (black) and fitted (magenta) girth profiles of one subject.
fn profile_chart(row: &EvalRow) -> String {
    let (w, h, pad) = (260.0, 320.0, 30.0);
    let pts: Vec<_> = row.profile.iter().collect();
    let gmax = pts
        .iter()
        .flat_map(|p| [p.true_mm, p.fitted_mm])
        .flatten()
        .fold(100.0f64, f64::max)
        * 1.05;
    let (ymin, ymax) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
        (a.0.min(p.height_m), a.1.max(p.height_m))
    });
    let sx = |g: f64| pad + (w - 2.0 * pad) * g / gmax;
    let sy = |y: f64| h - pad - (h - 2.0 * pad) * (y - ymin) / (ymax - ymin).max(1e-6);
    let line = |f: &dyn Fn(&super::ProfileSample) -> Option<f64>, col: &str| {
        let mut d = String::new();
        let mut pen = false;
        for p in &pts {
            match f(p) {
                Some(g) => {
                    let _ = write!(
                        d,
                        "{}{:.1},{:.1} ",
                        if pen { "L" } else { "M" },
                        sx(g),
                        sy(p.height_m)
                    );
                    pen = true;
                }
                None => pen = false,
            }
        }
        format!("<path d=\"{d}\" fill=\"none\" stroke=\"{col}\" stroke-width=\"1.5\"/>")
    };
    let mut s = format!("<svg width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" xmlns=\"http://www.w3.org/2000/svg\">");
    let _ = write!(
        s,
        "<text x=\"4\" y=\"14\" font-size=\"12\" font-weight=\"bold\">{}</text>",
        esc(&row.subject)
    );
    let _ = write!(
        s,
        "<line x1=\"{pad}\" x2=\"{pad}\" y1=\"{pad}\" y2=\"{}\" stroke=\"#888\"/>",
        h - pad
    );
    let _ = write!(
        s,
        "<line x1=\"{pad}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"#888\"/>",
        w - pad,
        h - pad,
        h - pad
    );
    let _ = write!(
        s,
        "<text x=\"{}\" y=\"{}\" font-size=\"10\" text-anchor=\"end\">{gmax:.0} mm</text>",
        w - pad,
        h - pad + 14.0
    );
    let _ = write!(
        s,
        "<text x=\"2\" y=\"{}\" font-size=\"10\">{ymin:.2} m</text>",
        h - pad + 14.0
    );
    let _ = write!(
        s,
        "<text x=\"2\" y=\"{}\" font-size=\"10\">{ymax:.2} m</text>",
        pad - 4.0
    );
    s.push_str(&line(&|p| p.true_mm, "#111"));
    s.push_str(&line(&|p| p.fitted_mm, "#e020b0"));
    s.push_str("</svg>");
    s
}

/// The whole report page: the measurement summary and error bars, surface and mask
/// scores, landmark and timing tables, then one card per subject.
pub fn report(table: &EvalTable, thumbs: &[Vec<Thumb>]) -> String {
    let mut s = String::from(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>fitstation evaluation</title><style>\
body{font-family:sans-serif;margin:20px;color:#222}table{border-collapse:collapse;font-size:13px}\
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#f0f0f0}\
.grid{display:flex;flex-wrap:wrap;gap:12px}.card{border:1px solid #ddd;padding:6px;border-radius:4px}\
.legend span{display:inline-block;margin-right:14px}</style></head><body>",
    );
    let _ = write!(
        s,
        "<h1>fitstation evaluation: {} subject(s)</h1>",
        table.rows.len()
    );
    measurements_section(&mut s, table);
    surface_section(&mut s, table);
    landmarks_section(&mut s, table);
    timings_section(&mut s, table);
    subjects_section(&mut s, table, thumbs);
    for f in &table.failures {
        let _ = write!(s, "<p style=\"color:#b00\">FAILED: {}</p>", esc(f));
    }
    s.push_str("</body></html>\n");
    s
}

/// The per-measurement MAE, bias and worst error, the worst girth, and each measurement's
/// bars of signed error per subject.
fn measurements_section(s: &mut String, table: &EvalTable) {
    s.push_str("<h2>Measurements (fitted - true, mm)</h2><table><tr><th>measurement</th><th>subjects</th><th>MAE</th><th>MAE 90 %</th><th>bias</th><th>worst</th><th>worst subject</th></tr>");
    let summary = table.summary();
    for m in &summary {
        let _ = write!(
            s,
            "<tr><td style=\"text-align:left\">{}</td><td>{}</td><td>{:.1}</td><td>{}</td><td>{:+.1}</td><td>{:+.1}</td><td style=\"text-align:left\">{}</td></tr>",
            esc(&m.name),
            m.subjects,
            m.mean_abs_error_mm,
            super::table::interval_cell(m.mae_interval_mm),
            m.mean_bias_mm,
            m.worst_error_mm,
            esc(&m.worst_subject)
        );
    }
    s.push_str("</table>");
    if let Some(w) = table.worst_girth() {
        let _ = write!(s, "<p><b>{}</b></p>", esc(&w.describe()));
    }
    s.push_str("<div class=\"grid\">");
    for m in &summary {
        let _ = write!(
            s,
            "<div class=\"card\">{}</div>",
            error_chart(table, &m.name)
        );
    }
    s.push_str("</div>");
}

/// Per subject: the surface distance to the true body and the mask IoU of each view.
fn surface_section(s: &mut String, table: &EvalTable) {
    s.push_str("<h2>Surface and masks</h2><table><tr><th>subject</th><th>surface mean mm</th><th>p95 mm</th><th>max mm</th><th>IoU front</th><th>IoU side</th></tr>");
    for r in &table.rows {
        let d = r
            .surface
            .map_or(["-".to_string(), "-".into(), "-".into()], |d| {
                [
                    format!("{:.1}", d.mean_mm),
                    format!("{:.1}", d.p95_mm),
                    format!("{:.1}", d.max_mm),
                ]
            });
        let iou = |v: &str| {
            r.mask_iou
                .get(v)
                .map_or("-".to_string(), |x| format!("{x:.3}"))
        };
        let _ = write!(
            s,
            "<tr><td style=\"text-align:left\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&r.subject),
            d[0],
            d[1],
            d[2],
            iou("front"),
            iou("side")
        );
    }
    s.push_str("</table>");
}

/// Per landmark of each source: mean 3-D distance and height errors over the subjects.
fn landmarks_section(s: &mut String, table: &EvalTable) {
    for source in LandmarkSource::ALL {
        let rows = table.landmark_summary(source);
        if rows.is_empty() {
            continue;
        }
        let _ = write!(
            s,
            "<h2>Landmarks: {} (mm)</h2><table><tr><th>landmark</th><th>subjects</th><th>mean 3-D distance</th><th>mean |height error|</th><th>worst |height error|</th></tr>",
            esc(source.title())
        );
        for l in rows {
            let _ = write!(
                s,
                "<tr><td style=\"text-align:left\">{}</td><td>{}</td><td>{:.1}</td><td>{:.1}</td><td>{:.1}</td></tr>",
                esc(&l.name),
                l.subjects,
                l.mean_distance_mm,
                l.mean_abs_height_mm,
                l.worst_abs_height_mm
            );
        }
        s.push_str("</table>");
    }
}

/// Stage timings over the subjects: median of the medians and the worst p95.
fn timings_section(s: &mut String, table: &EvalTable) {
    let timings = table.timing_summary();
    if !timings.is_empty() {
        s.push_str("<h2>Stage timings (ms)</h2><table><tr><th>stage</th><th>median</th><th>worst p95</th></tr>");
        for (k, t) in timings {
            let _ = write!(
                s,
                "<tr><td style=\"text-align:left\">{}</td><td>{:.2}</td><td>{:.2}</td></tr>",
                esc(&k),
                t.median,
                t.p95
            );
        }
        s.push_str("</table>");
    }
}

/// One card per subject: its true and fitted girth profiles and the overlay thumbnails.
fn subjects_section(s: &mut String, table: &EvalTable, thumbs: &[Vec<Thumb>]) {
    s.push_str("<h2>Subjects</h2><p class=\"legend\"><span style=\"color:#111\">&#9632; true girth profile</span><span style=\"color:#e020b0\">&#9632; fitted profile / fitted silhouette</span><span style=\"color:#28c83c\">&#9632; true silhouette outline</span></p>");
    for (i, r) in table.rows.iter().enumerate() {
        s.push_str("<div class=\"card\" style=\"margin-bottom:12px\"><div class=\"grid\">");
        s.push_str(&profile_chart(r));
        if let Some(ts) = thumbs.get(i) {
            for t in ts {
                let _ = write!(
                    s,
                    "<figure style=\"margin:0\"><img alt=\"{} overlay\" src=\"data:image/png;base64,{}\"/><figcaption>{}</figcaption></figure>",
                    esc(&t.view),
                    t.png_base64,
                    esc(&t.view)
                );
            }
        }
        s.push_str("</div></div>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }
}
