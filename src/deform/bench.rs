//! `fitstation bench deform`: times the deformers on a realistic refit problem in one run
//! and writes the problem for libigl's ARAP (`tests/libigl/arap_peer.py`), the outside
//! peer. Metres; times in milliseconds (wall clock, one thread).
//!
//! The problem (method.md section 3): control vertices are the slice extremes of the
//! mesh (slices one mean edge length thick in y; in each, the vertices of minimum and
//! maximum x and z), targets are those vertices moved by a smooth field (the torso
//! widened by [`TORSO_WIDENING`] with a raised-cosine profile in height), and the warm
//! refit moves every target by up to [`REFIT_NUDGE_M`] more. The fast decoder's refit is
//! timed three ways: with its rest linearisation, after re-linearising at the first
//! frame's result (timed on its own), and as a frame sequence from the previous result
//! (the live station). Both decoders stop at the same tolerance (`--tol-m`).

use super::{DecodeOptions, DecoderKind, LaplacianDeformer, MeanValueEncoding, MvcDeformer};
use crate::mesh::io::{read_mesh, read_obj, write_obj};
use crate::mesh::TriMesh;
use anyhow::Context;
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The raw MakeHuman body (decimetres, faces under `g body`, joints as `g joint-*`), in
/// the cache directory ([`crate::io::cache`]); optional (`--makehuman`).
pub use crate::io::cache::makehuman_base_obj;
/// The raw MakeHuman body's unit in metres.
pub const MAKEHUMAN_SCALE: f64 = 0.1;
/// Relative widening of the torso in the benchmark's target field.
pub const TORSO_WIDENING: f64 = 0.05;
/// Torso band of the target field, as fractions of the mesh height from its bottom.
pub const TORSO_BAND: (f64, f64) = (0.40, 0.80);
/// Amplitude of the warm-refit target nudge, metres.
pub const REFIT_NUDGE_M: f64 = 3e-3;
/// Wavelength of the warm-refit nudge along y, metres.
const REFIT_WAVELENGTH_M: f64 = 0.5;

/// `fitstation bench deform` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchArgs {
    /// Mesh to deform (OBJ or PLY). Default: the committed station template
    /// (templates/makehuman-adult.obj, built into the binary) with its rigid hands, feet
    /// and head.
    #[arg(long, conflicts_with = "makehuman")]
    pub mesh: Option<PathBuf>,
    /// Instead of the template: the raw MakeHuman base mesh (base.obj of the MPFB2
    /// assets, group "body" scaled from decimetres to metres, extremities from its joint
    /// groups). Give the path, or `cache` for the copy in the cache directory
    /// (see templates/PROVENANCE.md).
    #[arg(long)]
    pub makehuman: Option<PathBuf>,
    /// Scale applied to the positions of --mesh (1 for a mesh in metres).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Directory for the files handed to the libigl peer (mesh.obj, constraints.csv,
    /// refit.csv).
    #[arg(long, default_value_os_t = crate::io::cache::cache_dir().join("bench-deform"))]
    pub out: PathBuf,
    /// Do not run the libigl ARAP peer.
    #[arg(long)]
    pub no_libigl: bool,
    /// Convergence tolerance of both decoders, metres.
    #[arg(long, default_value_t = super::DEFAULT_MAX_MOVE_M)]
    pub tol_m: f64,
    /// Sweep cap of the paper-style decoder.
    #[arg(long, default_value_t = 200_000)]
    pub paper_max_sweeps: usize,
    /// Leave hands, feet and head free (the plain slice-extreme problem) instead of
    /// moving them rigidly as method.md section 3 does.
    #[arg(long)]
    pub free_extremities: bool,
    /// Repeats of each fast measurement (the median is reported).
    #[arg(long, default_value_t = 7)]
    pub repeats: usize,
}

/// A benchmark problem: control vertices, their targets, and nudged targets.
#[derive(Debug, Clone)]
pub struct DeformProblem {
    pub controls: Vec<u32>,
    pub targets: Vec<DVec3>,
    pub refit_targets: Vec<DVec3>,
    /// How many of the controls are slice extremes (the rest: rigid extremities).
    pub slice_controls: usize,
    /// Rigid extremities found (hands, feet, head), vertex counts.
    pub rigid_parts: Vec<usize>,
}

/// Extremities moved rigidly (method.md section 3): (name, joint at the cut, joint that
/// the cut plane faces away from). The part is every vertex beyond the plane through the
/// first joint perpendicular to the bone from the second, and closer to the first joint
/// than the bone is long.
pub const RIGID_EXTREMITIES: [(&str, &str, &str); 5] = [
    ("left hand", "joint-l-hand", "joint-l-elbow"),
    ("right hand", "joint-r-hand", "joint-r-elbow"),
    ("left foot", "joint-l-ankle", "joint-l-knee"),
    ("right foot", "joint-r-ankle", "joint-r-knee"),
    ("head", "joint-neck", "joint-spine-1"),
];

/// Rings around a rigid part where slice extremes give way to the part.
pub const RIGID_MARGIN_RINGS: usize = 3;

/// Centroids of the vertices of named face groups of an OBJ file (MakeHuman marks its
/// joints with `g joint-*` groups), scaled by `scale`; `None` for a missing group.
pub fn obj_group_centroids(
    path: &Path,
    names: &[&str],
    scale: f64,
) -> anyhow::Result<Vec<Option<DVec3>>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut verts: Vec<DVec3> = Vec::new();
    let mut used: Vec<Vec<usize>> = vec![Vec::new(); names.len()];
    let mut current: Option<usize> = None;
    for (lineno, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0.0; 3];
                for x in &mut c {
                    *x = it.next().and_then(|t| t.parse().ok()).with_context(|| {
                        format!("{}:{}: bad vertex", path.display(), lineno + 1)
                    })?;
                }
                verts.push(DVec3::from_array(c) * scale);
            }
            Some("g") => current = it.next().and_then(|g| names.iter().position(|n| *n == g)),
            Some("f") => {
                if let Some(k) = current {
                    for t in it {
                        let i: usize = t
                            .split('/')
                            .next()
                            .and_then(|x| x.parse().ok())
                            .with_context(|| {
                                format!("{}:{}: bad face", path.display(), lineno + 1)
                            })?;
                        used[k].push(i);
                    }
                }
            }
            _ => {}
        }
    }
    Ok(used
        .into_iter()
        .map(|mut ix| {
            ix.sort_unstable();
            ix.dedup();
            let pts: Vec<DVec3> = ix
                .iter()
                .filter_map(|&i| i.checked_sub(1).and_then(|i| verts.get(i)).copied())
                .collect();
            (!pts.is_empty()).then(|| pts.iter().sum::<DVec3>() / pts.len() as f64)
        })
        .collect())
}

/// Vertices of each rigid extremity given its cut joint and the joint it points away
/// from (see [`RIGID_EXTREMITIES`]).
pub fn extremity_vertices(mesh: &TriMesh, cut: DVec3, from: DVec3) -> Vec<u32> {
    let bone = cut - from;
    let len = bone.length();
    if !(len > 0.0) {
        return Vec::new();
    }
    let dir = bone / len;
    (0..mesh.vertex_count() as u32)
        .filter(|&v| {
            let d = mesh.positions[v as usize] - cut;
            d.dot(dir) > 0.0 && d.length() < len
        })
        .collect()
}

/// Slice extremes as control vertices (method.md section 3, "Control vertices"): slices
/// one mean edge length thick in y; in each, the vertices of min/max x and min/max z.
pub fn slice_extreme_controls(mesh: &TriMesh) -> Vec<u32> {
    let step = mesh.mean_edge_length();
    let Some(b) = mesh.bounds() else {
        return Vec::new();
    };
    if !(step > 0.0) {
        return Vec::new();
    }
    let slabs = ((b.size().y / step).floor() as usize) + 1;
    // Per slab: the vertex of min x, max x, min z, max z.
    let mut ext: Vec<[Option<u32>; 4]> = vec![[None; 4]; slabs];
    let key = |q: DVec3| [q.x, -q.x, q.z, -q.z];
    for (v, p) in mesh.positions.iter().enumerate() {
        let k = (((p.y - b.min.y) / step).floor() as usize).min(slabs - 1);
        let e = &mut ext[k];
        let keys = key(*p);
        for s in 0..4 {
            let take = match e[s] {
                None => true,
                Some(c) => keys[s] < key(mesh.positions[c as usize])[s],
            };
            if take {
                e[s] = Some(v as u32);
            }
        }
    }
    let mut out: Vec<u32> = ext
        .iter()
        .flat_map(|e| e.iter().flatten().copied())
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Smooth weight in [0, 1]: a raised cosine over the torso band, zero outside.
fn torso_profile(y: f64, y0: f64, height: f64) -> f64 {
    let t = ((y - y0) / height - TORSO_BAND.0) / (TORSO_BAND.1 - TORSO_BAND.0);
    if (0.0..=1.0).contains(&t) {
        0.5 * (1.0 - (std::f64::consts::TAU * t).cos())
    } else {
        0.0
    }
}

/// The benchmark's smooth target field: x and z scaled about the body axis by up to
/// `1 + TORSO_WIDENING` over the torso band.
pub fn widen_torso(mesh: &TriMesh, p: DVec3) -> DVec3 {
    let Some(b) = mesh.bounds() else { return p };
    let c = b.center();
    let s = 1.0 + TORSO_WIDENING * torso_profile(p.y, b.min.y, b.size().y);
    DVec3::new(c.x + (p.x - c.x) * s, p.y, c.z + (p.z - c.z) * s)
}

/// A smooth nudge of up to `REFIT_NUDGE_M`, varying along y.
pub fn refit_nudge(p: DVec3) -> DVec3 {
    let ph = std::f64::consts::TAU * p.y / REFIT_WAVELENGTH_M;
    REFIT_NUDGE_M * DVec3::new(ph.sin(), 0.3 * ph.cos(), ph.cos()) / (1.09f64).sqrt()
}

/// Builds the benchmark problem on `mesh`: slice extremes moved by [`widen_torso`];
/// also every vertex of the `rigid_parts` (hands, feet, head: [`extremity_vertices`]),
/// each part translated by the field at its centroid.
pub fn problem(mesh: &TriMesh, rigid_parts: &[Vec<u32>]) -> DeformProblem {
    let mut controls = slice_extreme_controls(mesh);
    let slice_controls = controls.len();
    let mut targets: Vec<DVec3> = controls
        .iter()
        .map(|&c| widen_torso(mesh, mesh.positions[c as usize]))
        .collect();
    let mut sizes = Vec::new();
    if !rigid_parts.is_empty() {
        // Slice extremes inside a rigid part, or within RIGID_MARGIN_RINGS rings of one,
        // give way to the part (their targets would tear the edges between them).
        let rings = mesh.one_rings();
        let mut near = vec![false; mesh.vertex_count()];
        for part in rigid_parts {
            part.iter().for_each(|&v| near[v as usize] = true);
        }
        for _ in 0..RIGID_MARGIN_RINGS {
            let grown: Vec<bool> = (0..mesh.vertex_count())
                .map(|v| near[v] || rings.neighbours(v).iter().any(|&u| near[u as usize]))
                .collect();
            near = grown;
        }
        let keep: Vec<(u32, DVec3)> = controls
            .iter()
            .zip(&targets)
            .filter(|(c, _)| !near[**c as usize])
            .map(|(c, t)| (*c, *t))
            .collect();
        controls = keep.iter().map(|k| k.0).collect();
        targets = keep.iter().map(|k| k.1).collect();
        for part in rigid_parts {
            let centroid = part
                .iter()
                .map(|&v| mesh.positions[v as usize])
                .sum::<DVec3>()
                / part.len() as f64;
            let shift = widen_torso(mesh, centroid) - centroid;
            for &v in part {
                controls.push(v);
                targets.push(mesh.positions[v as usize] + shift);
            }
            sizes.push(part.len());
        }
    }
    let refit_targets = targets.iter().map(|&t| t + refit_nudge(t)).collect();
    DeformProblem {
        controls,
        targets,
        refit_targets,
        slice_controls,
        rigid_parts: sizes,
    }
}

fn median_ms(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs.get(xs.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Fastest of the repeats: on a machine shared with other work the median carries the
/// waits for the other processes, the minimum is closest to the cost of the code itself
/// (both are printed for the refits).
fn min_ms(xs: &[f64]) -> f64 {
    xs.iter().copied().fold(f64::NAN, f64::min)
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Peak resident memory of this process, MB (Linux `/proc/self/status` VmHWM).
fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// The committed station template (built into the binary), its mesh in metres.
fn default_template() -> anyhow::Result<&'static crate::body::Template> {
    Ok(crate::body::ShapeLibrary::shared()
        .context("the committed template (templates/makehuman-adult.fsl)")?
        .template())
}

/// Writes the peer's constraint file: `index,x,y,z` per control vertex, metres.
fn write_constraints(path: &Path, controls: &[u32], targets: &[DVec3]) -> anyhow::Result<()> {
    let mut s = String::from("index,x,y,z\n");
    for (c, t) in controls.iter().zip(targets) {
        s.push_str(&format!("{c},{:.9},{:.9},{:.9}\n", t.x, t.y, t.z));
    }
    crate::io::atomic::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// The raw MakeHuman file `--makehuman` names (`cache`: the cache directory's copy).
pub fn makehuman_path(args: &BenchArgs) -> Option<PathBuf> {
    args.makehuman.as_ref().map(|p| {
        if p.as_os_str() == "cache" {
            makehuman_base_obj()
        } else {
            p.clone()
        }
    })
}

/// Loads the bench mesh: `--mesh` scaled by `--scale`, the raw MakeHuman body
/// (`--makehuman`), or by default the committed template.
pub fn load_mesh(args: &BenchArgs) -> anyhow::Result<TriMesh> {
    let mut mesh = match (&args.mesh, makehuman_path(args)) {
        (Some(p), _) => {
            let mut m = read_mesh(p).with_context(|| format!("reading {}", p.display()))?;
            let s = args.scale;
            m.map_positions(|q| q * s);
            m
        }
        (None, Some(p)) => {
            let mut m = read_obj(&p, Some("body")).with_context(|| {
                format!(
                    "reading the raw MakeHuman mesh {} (leave out --makehuman for the committed template)",
                    p.display()
                )
            })?;
            m.map_positions(|q| q * MAKEHUMAN_SCALE);
            m
        }
        (None, None) => return Ok(default_template()?.mesh.clone()),
    };
    mesh.compact();
    mesh.validate()
        .map_err(|e| anyhow::anyhow!("bench mesh: {e}"))?;
    Ok(mesh)
}

/// The rigid extremities of the default MakeHuman mesh from its joint groups; none for
/// another mesh (its joints are unknown here).
pub fn rigid_parts(args: &BenchArgs) -> anyhow::Result<Vec<Vec<u32>>> {
    if args.mesh.is_some() {
        println!("note: --mesh given: no joints known, hands, feet and head stay free");
        return Ok(Vec::new());
    }
    let Some(raw) = makehuman_path(args) else {
        let r = &default_template()?.info.rigid;
        return Ok([
            &r.hand_left,
            &r.hand_right,
            &r.foot_left,
            &r.foot_right,
            &r.head,
        ]
        .into_iter()
        .cloned()
        .collect());
    };
    let mesh = load_mesh(args)?;
    let names: Vec<&str> = RIGID_EXTREMITIES.iter().flat_map(|e| [e.1, e.2]).collect();
    let c = obj_group_centroids(&raw, &names, MAKEHUMAN_SCALE)?;
    let mut out = Vec::new();
    for (k, e) in RIGID_EXTREMITIES.iter().enumerate() {
        match (c[2 * k], c[2 * k + 1]) {
            (Some(cut), Some(from)) => out.push(extremity_vertices(&mesh, cut, from)),
            _ => println!("note: joint groups of the {} missing; it stays free", e.0),
        }
    }
    Ok(out)
}

/// Runs the benchmark and prints its figures: the mean value encoding, the fast
/// decoder's setup, decodes, refits and frame sequence, its frozen-offset variant, the
/// paper's decoder and Laplacian editing, then the libigl peer on the same problem.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    crate::io::atomic::check_dir(&args.out).map_err(|e| anyhow::anyhow!("--out: {e}"))?;
    let mesh = load_mesh(&args)?;
    let parts = if args.free_extremities {
        Vec::new()
    } else {
        rigid_parts(&args)?
    };
    let prob = problem(&mesh, &parts);
    let repeats = args.repeats.max(1);
    describe_problem(&mesh, &prob);
    let encoding = time_encoding(&mesh, repeats)?;
    // Re-linearisation is timed on its own below, not folded into a solve.
    let opts = DecodeOptions {
        max_move_m: args.tol_m,
        max_iterations: 200,
        relinearise_after: usize::MAX,
        ..Default::default()
    };
    let mut fast = time_fast_setup(&mesh, &encoding, &prob, opts)?;
    let decodes = time_fast_decodes(&mut fast, &mesh, &prob, repeats)?;
    time_frame_sequence(&mut fast, &prob, &decodes.warm_pos, repeats)?;
    time_frozen_variant(&mesh, &encoding, &prob, opts)?;
    time_paper_decoder(&args, &mesh, encoding, &prob, opts, &decodes)?;
    time_laplacian(&mesh, &prob, opts, repeats)?;

    println!(
        "memory:              {:8.1} MB fast engine heap, {:.1} MB process peak RSS",
        fast.heap_bytes() as f64 / 1e6,
        peak_rss_mb().unwrap_or(f64::NAN)
    );

    // Files for the outside peer, then the peer itself.
    crate::io::atomic::create_dir(&args.out)?;
    let mesh_path = args.out.join("mesh.obj");
    write_obj(&mesh_path, &mesh)?;
    let cons = args.out.join("constraints.csv");
    write_constraints(&cons, &prob.controls, &prob.targets)?;
    let refit = args.out.join("refit.csv");
    write_constraints(&refit, &prob.controls, &prob.refit_targets)?;
    println!("peer input:          {}", args.out.display());
    if !args.no_libigl {
        run_libigl_peer(&mesh_path, &cons, &refit, decodes.fast_ms, decodes.warm_ms);
    }
    Ok(())
}

/// The mesh and the deformation problem: its controls and how far their targets move.
fn describe_problem(mesh: &TriMesh, prob: &DeformProblem) {
    let n = mesh.vertex_count();
    println!(
        "mesh: {} vertices, {} triangles, {} boundary edges, mean edge {:.2} mm",
        n,
        mesh.triangle_count(),
        mesh.boundary_edge_count(),
        mesh.mean_edge_length() * 1e3
    );
    let max_target_move = prob
        .controls
        .iter()
        .zip(&prob.targets)
        .map(|(&c, t)| (*t - mesh.positions[c as usize]).length())
        .fold(0.0, f64::max);
    println!(
        "problem: {} control vertices ({} slice extremes, rigid parts {:?}), targets moved up to {:.1} mm (torso +{:.0}%), refit nudge {:.1} mm",
        prob.controls.len(),
        prob.slice_controls,
        prob.rigid_parts,
        max_target_move * 1e3,
        TORSO_WIDENING * 100.0,
        REFIT_NUDGE_M * 1e3
    );
}

/// Times the mean value encoding of every vertex in its one-ring's tangent plane.
fn time_encoding(mesh: &TriMesh, repeats: usize) -> anyhow::Result<MeanValueEncoding> {
    let n = mesh.vertex_count();
    let t = Instant::now();
    let rings = mesh.one_rings();
    let rings_ms = ms(t);
    let mut enc_times = Vec::new();
    let mut encoding = None;
    for _ in 0..repeats {
        let t = Instant::now();
        let e = MeanValueEncoding::encode(mesh, &rings);
        enc_times.push(ms(t));
        encoding = Some(e);
    }
    let encoding = encoding.context("no encoding")?;
    let degenerate = (0..n)
        .filter(|&v| encoding.kind(v) != super::RingEncodingKind::Tangent)
        .count();
    println!(
        "encoding:            {:8.2} ms median of {repeats} (one-rings {:.2} ms; {} degenerate rings)",
        median_ms(enc_times),
        rings_ms,
        degenerate
    );
    Ok(encoding)
}

/// Times the fast decoder's analysis and factorisation (and, for comparison, the
/// frozen-offset engine's full-size analysis kept across control sets).
fn time_fast_setup(
    mesh: &TriMesh,
    encoding: &MeanValueEncoding,
    prob: &DeformProblem,
    opts: DecodeOptions,
) -> anyhow::Result<MvcDeformer> {
    let t = Instant::now();
    let mut fast =
        MvcDeformer::from_encoding(mesh, encoding.clone(), DecoderKind::FastGaussNewton, opts)?;
    let new_ms = ms(t);
    let t = Instant::now();
    fast.set_controls(&prob.controls)?;
    let first_controls_ms = ms(t);
    let t = Instant::now();
    fast.set_controls(&prob.controls)?;
    let same_controls_ms = ms(t);
    println!(
        "fast setup:          {:8.2} ms new, {:.2} ms first control set (symbolic + numeric, {} factor values), {:.3} ms same set again",
        new_ms,
        first_controls_ms,
        fast.factor_len(),
        same_controls_ms
    );
    // The frozen-offset engine's other strategy: one full-size analysis kept across
    // control sets.
    let full_opts = DecodeOptions {
        symbolic: super::SymbolicReuse::AcrossControlSets,
        linearisation: super::Linearisation::FrozenOffsets,
        ..opts
    };
    let t = Instant::now();
    let mut full = MvcDeformer::from_encoding(
        mesh,
        encoding.clone(),
        DecoderKind::FastGaussNewton,
        full_opts,
    )?;
    let full_new_ms = ms(t);
    let t = Instant::now();
    full.set_controls(&prob.controls)?;
    let full_factor_ms = ms(t);
    let mut pos = mesh.positions.clone();
    let t = Instant::now();
    let r = full.solve(&prob.targets, &mut pos)?;
    println!(
        "  (frozen offsets, full-size variant: {:.2} ms analysis once per mesh, {:.2} ms numeric factor per control set, {} factor values, decode from rest {:.2} ms in {} steps)",
        full_new_ms,
        full_factor_ms,
        full.factor_len(),
        ms(t),
        r.iterations
    );
    Ok(fast)
}

/// The fast decoder's figures that the paper's decoder and the peer are compared with:
/// median decode from rest and warm refit, and the shapes they reached.
struct FastDecodes {
    fast_ms: f64,
    warm_ms: f64,
    fast_pos: Vec<DVec3>,
    warm_pos: Vec<DVec3>,
}

/// Times the fast decoder over frame sequences: a decode from the rest shape, a warm
/// refit with the rest linearisation, re-linearising, and the refit again.
fn time_fast_decodes(
    fast: &mut MvcDeformer,
    mesh: &TriMesh,
    prob: &DeformProblem,
    repeats: usize,
) -> anyhow::Result<FastDecodes> {
    // Each repeat is a frame sequence: a decode from the rest shape (linearised at rest,
    // as after `set_controls`), a warm refit after the targets moved a few millimetres
    // with that linearisation, then the same refit after re-linearising at the first
    // frame's result (what a station does once per subject).
    let mut fast_times = Vec::new();
    let mut warm_times = Vec::new();
    let mut stale_times = Vec::new();
    let mut fast_pos = mesh.positions.clone();
    let mut warm_pos = mesh.positions.clone();
    let mut fast_report = Default::default();
    let mut warm_report = Default::default();
    let mut stale_report = Default::default();
    let mut relin_ms = Vec::new();
    for _ in 0..repeats {
        fast.relinearise(&mesh.positions)?;
        fast.reset_history();
        fast_pos.copy_from_slice(&mesh.positions);
        let t = Instant::now();
        fast_report = fast.solve(&prob.targets, &mut fast_pos)?;
        fast_times.push(ms(t));
        warm_pos.copy_from_slice(&fast_pos);
        let t = Instant::now();
        stale_report = fast.solve(&prob.refit_targets, &mut warm_pos)?;
        stale_times.push(ms(t));
        let t = Instant::now();
        fast.relinearise(&fast_pos)?;
        relin_ms.push(ms(t));
        warm_pos.copy_from_slice(&fast_pos);
        let t = Instant::now();
        warm_report = fast.solve(&prob.refit_targets, &mut warm_pos)?;
        warm_times.push(ms(t));
    }
    let fast_ms = median_ms(fast_times);
    println!(
        "fast decode (rest):  {:8.2} ms median of {repeats}: {} Gauss-Newton steps, last move {:.2e} m, residual {:.2e} m, converged {} (coupled system {})",
        fast_ms, fast_report.iterations, fast_report.max_move_m, fast_report.residual_m, fast_report.converged, fast.uses_coupled_system()
    );
    println!(
        "fast refit, rest linearisation: {:.2} ms median of {repeats}: {} steps, last move {:.2e} m, residual {:.2e} m, converged {}",
        median_ms(stale_times), stale_report.iterations, stale_report.max_move_m, stale_report.residual_m, stale_report.converged
    );
    println!(
        "re-linearise at frame 1: {:.2} ms median of {repeats} (finite-difference Jacobian + numeric refactor, once per subject)",
        median_ms(relin_ms)
    );
    let warm_min_ms = min_ms(&warm_times);
    let warm_ms = median_ms(warm_times);
    println!(
        "fast warm refit:     {:8.2} ms median of {repeats} (fastest {:.2} ms): {} steps, last move {:.2e} m, residual {:.2e} m, converged {} (linearised at the previous frame)",
        warm_ms, warm_min_ms, warm_report.iterations, warm_report.max_move_m, warm_report.residual_m, warm_report.converged
    );
    Ok(FastDecodes {
        fast_ms,
        warm_ms,
        fast_pos,
        warm_pos,
    })
}

/// Times the live station's case: frame after frame from the previous result, the
/// targets alternating between the two sets; then where a chord step's time goes.
fn time_frame_sequence(
    fast: &mut MvcDeformer,
    prob: &DeformProblem,
    warm_pos: &[DVec3],
    repeats: usize,
) -> anyhow::Result<()> {
    // The live station: frame after frame from the previous result (linearised at the
    // first frame's result above), the targets alternating between the two sets.
    let frames = 2 * repeats;
    let mut pos = warm_pos.to_vec();
    let mut times = Vec::with_capacity(frames);
    let (mut lo, mut hi, mut all_converged) = (usize::MAX, 0usize, true);
    for k in 0..frames {
        let t_set = if k % 2 == 0 {
            &prob.targets
        } else {
            &prob.refit_targets
        };
        let t = Instant::now();
        let r = fast.solve(t_set, &mut pos)?;
        times.push(ms(t));
        lo = lo.min(r.iterations);
        hi = hi.max(r.iterations);
        all_converged &= r.converged;
    }
    let fastest = min_ms(&times);
    println!(
        "fast frame sequence: {:8.2} ms median of {frames} frames (fastest {:.2} ms; targets moving {:.1} mm per frame, from the previous frame): {lo}-{hi} steps, all converged {all_converged}",
        median_ms(times),
        fastest,
        REFIT_NUDGE_M * 1e3
    );
    // Where a chord step's time goes (after the sequence: this resets the residual
    // remembered at its result).
    if let Some((residual_ms, solve_ms, read, held)) = fast.step_part_times(warm_pos, repeats) {
        println!(
            "fast step parts:     {:8.2} ms residual pass (every free vertex decoded), {:.2} ms block-LU solve ({read} of the factor's {held} blocks read), medians of {repeats}",
            residual_ms, solve_ms
        );
    }
    Ok(())
}

/// Times the frozen-offset variant (scalar factor, Anderson mixing) for comparison.
fn time_frozen_variant(
    mesh: &TriMesh,
    encoding: &MeanValueEncoding,
    prob: &DeformProblem,
    opts: DecodeOptions,
) -> anyhow::Result<()> {
    let frozen_opts = DecodeOptions {
        linearisation: super::Linearisation::FrozenOffsets,
        ..opts
    };
    let mut frozen = MvcDeformer::from_encoding(
        mesh,
        encoding.clone(),
        DecoderKind::FastGaussNewton,
        frozen_opts,
    )?;
    frozen.set_controls(&prob.controls)?;
    let mut pos = mesh.positions.clone();
    let t = Instant::now();
    let r = frozen.solve(&prob.targets, &mut pos)?;
    let rest_ms = ms(t);
    let t = Instant::now();
    let w = frozen.solve(&prob.refit_targets, &mut pos)?;
    println!(
        "  (frozen-offset variant: decode from rest {:.2} ms in {} steps, warm refit {:.2} ms in {} steps)",
        rest_ms,
        r.iterations,
        ms(t),
        w.iterations
    );
    Ok(())
}

/// Times the paper's iterative decoder to the same tolerance and compares its shape and
/// time with the fast decoder's.
fn time_paper_decoder(
    args: &BenchArgs,
    mesh: &TriMesh,
    encoding: MeanValueEncoding,
    prob: &DeformProblem,
    opts: DecodeOptions,
    fast: &FastDecodes,
) -> anyhow::Result<()> {
    let FastDecodes {
        fast_pos, fast_ms, ..
    } = fast;
    let paper_opts = DecodeOptions {
        max_iterations: args.paper_max_sweeps,
        ..opts
    };
    let mut paper =
        MvcDeformer::from_encoding(mesh, encoding, DecoderKind::PaperIterative, paper_opts)?;
    paper.set_controls(&prob.controls)?;
    let mut paper_pos = mesh.positions.clone();
    let t = Instant::now();
    let paper_report = paper.solve(&prob.targets, &mut paper_pos)?;
    let paper_ms = ms(t);
    println!(
        "paper decode (rest): {:8.2} ms: {} sweeps, last move {:.2e} m, residual {:.2e} m, converged {}",
        paper_ms, paper_report.iterations, paper_report.max_move_m, paper_report.residual_m, paper_report.converged
    );
    let agree = paper_pos
        .iter()
        .zip(fast_pos)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, f64::max);
    println!(
        "decoders agree to:   {:8.4} mm (max vertex distance)",
        agree * 1e3
    );
    println!("ratio paper / fast:  {:8.1}x", paper_ms / fast_ms);
    Ok(())
}

/// Times Laplacian editing on the same problem, for reference.
fn time_laplacian(
    mesh: &TriMesh,
    prob: &DeformProblem,
    opts: DecodeOptions,
    repeats: usize,
) -> anyhow::Result<()> {
    let t = Instant::now();
    let mut lap = LaplacianDeformer::new(mesh, opts)?;
    let lap_new_ms = ms(t);
    let t = Instant::now();
    lap.set_controls(&prob.controls)?;
    let lap_factor_ms = ms(t);
    let mut lap_pos = mesh.positions.clone();
    let mut lap_times = Vec::new();
    for _ in 0..repeats {
        let t = Instant::now();
        lap.solve(&prob.targets, &mut lap_pos)?;
        lap_times.push(ms(t));
    }
    println!(
        "laplacian:           {:8.2} ms per solve (build+analysis {:.2} ms, factor {:.2} ms)",
        median_ms(lap_times),
        lap_new_ms,
        lap_factor_ms
    );
    Ok(())
}

/// Runs `tests/libigl/arap_peer.py` and prints its figures next to ours.
fn run_libigl_peer(mesh: &Path, cons: &Path, refit: &Path, fast_ms: f64, warm_ms: f64) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/libigl/arap_peer.py");
    let out = std::process::Command::new("python3")
        .arg(&script)
        .args(["--mesh".as_ref(), mesh.as_os_str()])
        .args(["--constraints".as_ref(), cons.as_os_str()])
        .args(["--refit".as_ref(), refit.as_os_str()])
        .env("OMP_NUM_THREADS", "1")
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout);
            println!("libigl ARAP peer (python3 {}):", script.display());
            let mut solve_ms = None;
            for line in text.lines() {
                println!("  {line}");
                if let Some(v) = line.strip_prefix("solve_ms ") {
                    solve_ms = v.trim().parse::<f64>().ok();
                }
            }
            if let Some(s) = solve_ms {
                println!("ratio igl ARAP solve / fast decode from rest: {:.1}x, / fast warm refit: {:.1}x", s / fast_ms, s / warm_ms);
            }
        }
        Ok(o) => println!(
            "libigl ARAP peer did not run (exit {:?}): {}",
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).trim()
        ),
        Err(e) => println!("libigl ARAP peer did not run: python3: {e}"),
    }
}
