//! Hostile input, bounded: files that claim more than they hold, files that are not
//! files, broken glTF structure, huge polygons and piles of identical triangles. Each
//! case runs the command line on a file the test writes and checks the exit code, that
//! the message names the file, and the peak memory of that one child (`wait4`); a
//! watchdog kills a child that does not answer, so that a hang fails instead of
//! blocking the suite (no timing is asserted).

use std::ffi::OsStr;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What a run of the command line did.
struct Outcome {
    code: Option<i32>,
    stderr: String,
    /// Peak resident memory of the child, in bytes.
    peak: u64,
}

/// Longest a child may take before it counts as hung (every case answers in well
/// under a second on an idle machine; this allows for a loaded one).
const WATCHDOG: Duration = Duration::from_secs(120);

/// Runs `raytracer ARGS`, waiting for this child alone, with its resource usage.
#[cfg(target_os = "linux")]
// Reaped by `wait4`, which also gives this child's own resource usage.
#[allow(clippy::zombie_processes)]
fn run<S: AsRef<OsStr>>(args: &[S]) -> Outcome {
    let mut child = Command::new(env!("CARGO_BIN_EXE_raytracer"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = Vec::new();
        pipe.read_to_end(&mut text).unwrap();
        text
    });
    let pid = child.id() as libc::pid_t;
    let start = Instant::now();
    let (status, usage) = loop {
        let mut status = 0;
        // SAFETY: `wait4` only fills the status and the struct it is given.
        let (reaped, usage) = unsafe {
            let mut usage = std::mem::zeroed::<libc::rusage>();
            let reaped = libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage);
            (reaped, usage)
        };
        if reaped == pid {
            break (status, usage);
        }
        assert_eq!(reaped, 0, "wait4 failed");
        if start.elapsed() > WATCHDOG {
            child.kill().unwrap();
            panic!("raytracer {:?} did not answer", args_text(args));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = String::from_utf8_lossy(&reader.join().unwrap()).into_owned();
    Outcome {
        code: libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status)),
        stderr,
        peak: usage.ru_maxrss as u64 * 1024,
    }
}

fn args_text<S: AsRef<OsStr>>(args: &[S]) -> Vec<String> {
    args.iter()
        .map(|a| a.as_ref().to_string_lossy().into_owned())
        .collect()
}

/// `render SCENE -o DIR/out.png` at 32 x 24 pixels.
fn render(scene: &Path) -> Outcome {
    let out = scene.with_file_name("out.png");
    let _ = std::fs::remove_file(&out);
    run(&[
        OsStr::new("render"),
        scene.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--width"),
        OsStr::new("32"),
        OsStr::new("--height"),
        OsStr::new("24"),
    ])
}

/// An error naming `file`, from a child whose peak memory stayed under `mib` MiB.
fn assert_refused(outcome: &Outcome, file: &Path, mib: u64) {
    assert_eq!(outcome.code, Some(2), "{}", outcome.stderr);
    assert!(
        outcome.stderr.contains(&file.display().to_string()),
        "the message does not name {}: {}",
        file.display(),
        outcome.stderr
    );
    assert!(!outcome.stderr.contains("panicked"), "{}", outcome.stderr);
    assert!(
        outcome.peak < mib << 20,
        "peak memory {} MiB: {}",
        outcome.peak >> 20,
        outcome.stderr
    );
}

/// A success whose warnings include one containing every part of `parts`.
fn assert_warned(outcome: &Outcome, parts: &[&str], mib: u64) {
    assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
    assert!(
        outcome
            .stderr
            .lines()
            .any(|line| line.starts_with("warning:") && parts.iter().all(|p| line.contains(p))),
        "no warning with {parts:?}: {}",
        outcome.stderr
    );
    assert!(
        outcome.peak < mib << 20,
        "peak memory {} MiB",
        outcome.peak >> 20
    );
}

#[cfg(target_os = "linux")]
#[test]
fn a_compressed_scene_of_binary_data_is_refused_after_its_first_block() {
    let dir = tempfile::tempdir().unwrap();
    // 512 MiB of NUL bytes in about half a megabyte.
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    let block = vec![0u8; 1 << 20];
    for _ in 0..512 {
        encoder.write_all(&block).unwrap();
    }
    let bomb = encoder.finish().unwrap();
    for name in ["bomb.obj.gz", "bomb.toml.gz", "bomb.ply.gz"] {
        let path = dir.path().join(name);
        std::fs::write(&path, &bomb).unwrap();
        let outcome = render(&path);
        assert_refused(&outcome, &path, 64);
        assert!(
            outcome.stderr.contains("binary data") || outcome.stderr.contains("ply"),
            "{name}: {}",
            outcome.stderr
        );
        assert!(!dir.path().join("out.png").exists());
    }
}

// ---------------------------------------------------------------------------------
// Textures: images that claim too much, and files that are not images.

/// A PNG whose header claims `width` x `height` RGB texels, followed by one small
/// compressed row of data (the decoder must refuse before allocating the image).
fn png_claiming(width: u32, height: u32) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], body: &[u8]) {
        out.extend((body.len() as u32).to_be_bytes());
        out.extend(kind);
        out.extend(body);
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(body);
        out.extend(crc.sum().to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut header = Vec::new();
    header.extend(width.to_be_bytes());
    header.extend(height.to_be_bytes());
    header.extend([8, 2, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &header);
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(&vec![0u8; 1 << 16]).unwrap();
    chunk(&mut png, b"IDAT", &encoder.finish().unwrap());
    chunk(&mut png, b"IEND", &[]);
    png
}

/// A textured quad: `scene.obj`, and `m.mtl` whose line 3 is `map_Kd TEXTURE`.
fn textured_scene(dir: &Path, texture: &str) -> PathBuf {
    std::fs::write(
        dir.join("m.mtl"),
        format!("newmtl t\nKd 1 1 1\nmap_Kd {texture}\n"),
    )
    .unwrap();
    let obj = dir.join("scene.obj");
    std::fs::write(
        &obj,
        "mtllib m.mtl\nv -1 -1 -3\nv 1 -1 -3\nv 1 1 -3\nv -1 1 -3\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         usemtl t\nf 1/1 2/2 3/3 4/4\nP 0 0 0 1 1 1\n",
    )
    .unwrap();
    obj
}

#[cfg(target_os = "linux")]
#[test]
fn an_image_claiming_too_many_texels_is_a_warning_and_the_surface_renders_without_it() {
    let dir = tempfile::tempdir().unwrap();
    // Beyond the size limit, and within it but beyond the memory limit (16,000 x
    // 16,000 RGB texels are 732 MiB).
    for (width, height) in [(100_000, 100_000), (16_000, 16_000), (1, 4_000_000_000)] {
        std::fs::write(dir.path().join("huge.png"), png_claiming(width, height)).unwrap();
        let scene = textured_scene(dir.path(), "huge.png");
        let outcome = render(&scene);
        let mtl_line = format!("{}:3:", dir.path().join("m.mtl").display());
        assert_warned(
            &outcome,
            &[&mtl_line, "huge.png", "renders without it"],
            256,
        );
        assert!(dir.path().join("out.png").exists());
    }
}

#[cfg(target_os = "linux")]
#[test]
fn textures_that_are_not_image_files_are_warnings() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("folder.png")).unwrap();
    std::fs::write(dir.path().join("text.png"), "not an image\n").unwrap();
    let fifo = dir.path().join("pipe.png");
    let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: `mkfifo` reads the NUL-terminated path it is given.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    for (texture, reason) in [
        ("pipe.png", "not a regular file"),
        ("/dev/zero", "not a regular file"),
        ("/dev/urandom", "not a regular file"),
        ("folder.png", "folder"),
        ("text.png", "t.png': "),
    ] {
        let scene = textured_scene(dir.path(), texture);
        let outcome = render(&scene);
        assert_warned(&outcome, &["m.mtl:3:", texture, reason], 128);
    }
}

#[cfg(target_os = "linux")]
#[test]
fn material_libraries_that_are_not_files_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("folder.mtl")).unwrap();
    for library in ["/dev/zero", "/dev/urandom", "folder.mtl"] {
        let obj = dir.path().join("scene.obj");
        std::fs::write(
            &obj,
            format!("mtllib {library}\nv 0 0 -1\nv 1 0 -1\nv 0 1 -1\nf 1 2 3\n"),
        )
        .unwrap();
        let outcome = render(&obj);
        assert!(outcome.code.is_some(), "{}", outcome.stderr);
        assert!(
            outcome.stderr.contains(&format!("{}:1:", obj.display()))
                && outcome.stderr.contains(library),
            "{library}: {}",
            outcome.stderr
        );
        assert!(
            outcome.peak < 128 << 20,
            "{library}: {} MiB",
            outcome.peak >> 20
        );
    }
}

// ---------------------------------------------------------------------------------
// PLY: counts the file cannot hold.

#[cfg(target_os = "linux")]
#[test]
fn ply_counts_beyond_what_the_file_holds_fail_without_allocating_for_them() {
    let dir = tempfile::tempdir().unwrap();
    let header = |format: &str, vertices: &str, faces: &str, count_type: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
             property float z\nelement face {faces}\nproperty list {count_type} int vertex_indices\nend_header\n"
        )
        .into_bytes()
    };
    let mut cases: Vec<(&str, Vec<u8>)> = Vec::new();
    // A trillion vertices in 36 bytes.
    let mut bytes = header("binary_little_endian", "1000000000000", "1", "uchar");
    bytes.extend([0u8; 36]);
    cases.push(("vertices.ply", bytes));
    // Four billion faces.
    let mut bytes = header("binary_little_endian", "3", "4000000000", "uchar");
    bytes.extend([0u8; 36]);
    bytes.extend([3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    cases.push(("faces.ply", bytes));
    // A face of four billion corners, in binary and in ascii.
    let mut bytes = header("binary_little_endian", "3", "1", "uint");
    bytes.extend([0u8; 36]);
    bytes.extend(4_000_000_000u32.to_le_bytes());
    bytes.extend([0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    cases.push(("corners.ply", bytes));
    let mut bytes = header("ascii", "3", "1", "uint");
    bytes.extend(b"0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n");
    cases.push(("corners-ascii.ply", bytes));
    for (name, bytes) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        assert_refused(&render(&path), &path, 64);
    }
}

// ---------------------------------------------------------------------------------
// glTF: structure, bounds, and files that are not files.

/// One triangle: three float positions (36 bytes), then three u16 indices and two
/// bytes of padding.
fn triangle_buffer() -> Vec<u8> {
    let mut bytes = Vec::new();
    for p in [[-1.0f32, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]] {
        for c in p {
            bytes.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2] {
        bytes.extend(i.to_le_bytes());
    }
    bytes.extend([0, 0]);
    bytes
}

/// A glTF file of one triangle mesh, with `nodes` (JSON array text; node 0 is the
/// scene's root), `accessors` replacing the two default ones if given, and the buffer
/// at `uri` (written as `tri.bin` beside the file when `uri` is that).
fn gltf_scene(dir: &Path, nodes: &str, accessors: Option<&str>, uri: &str) -> PathBuf {
    std::fs::write(dir.join("tri.bin"), triangle_buffer()).unwrap();
    let accessors = accessors.unwrap_or(
        r#"[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-1,-1,-3],"max":[1,1,-3]},
            {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]"#,
    );
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":{accessors},
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":6}}],
        "buffers":[{{"uri":"{uri}","byteLength":44}}]}}"#
    );
    let path = dir.join("scene.gltf");
    std::fs::write(&path, json).unwrap();
    path
}

#[cfg(target_os = "linux")]
#[test]
fn a_node_cycle_is_an_error_naming_the_node() {
    let dir = tempfile::tempdir().unwrap();
    let path = gltf_scene(
        dir.path(),
        r#"[{"children":[1]},{"children":[2],"name":"elbow"},{"children":[1],"mesh":0}]"#,
        None,
        "tri.bin",
    );
    let outcome = render(&path);
    assert_refused(&outcome, &path, 64);
    assert!(
        outcome.stderr.contains("node 1 ('elbow')") && outcome.stderr.contains("cycle"),
        "{}",
        outcome.stderr
    );
}

#[cfg(target_os = "linux")]
#[test]
fn a_hierarchy_of_100000_levels_is_read_without_recursion() {
    let dir = tempfile::tempdir().unwrap();
    let levels = 100_000;
    let mut nodes: Vec<String> = (0..levels - 1)
        .map(|i| format!(r#"{{"children":[{}]}}"#, i + 1))
        .collect();
    nodes.push(r#"{"mesh":0}"#.into());
    let path = gltf_scene(
        dir.path(),
        &format!("[{}]", nodes.join(",")),
        None,
        "tri.bin",
    );
    let outcome = run(&[OsStr::new("info"), path.as_os_str()]);
    assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
    let outcome = render(&path);
    assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
    assert!(outcome.peak < 256 << 20, "{} MiB", outcome.peak >> 20);
}

#[cfg(target_os = "linux")]
#[test]
fn accessors_outside_their_views_and_views_outside_their_buffers_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let position = |extra: &str| {
        format!(
            r#"[{{"bufferView":0,"componentType":5126,"type":"VEC3","min":[-1,-1,-3],"max":[1,1,-3],{extra}}},
                {{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}]"#
        )
    };
    let indices = |extra: &str| {
        format!(
            r#"[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-1,-1,-3],"max":[1,1,-3]}},
                {{"bufferView":1,"type":"SCALAR",{extra}}}]"#
        )
    };
    let cases = [
        // More elements than the view holds; a count that overflows; none at all.
        (position(r#""count":1000"#), "accessor 0"),
        (position(r#""count":4000000000000000000"#), "accessor 0"),
        (position(r#""count":0"#), "count of 0"),
        (position(r#""count":3,"byteOffset":30"#), "accessor 0"),
        // Indices of floats, and indices outside their view.
        (indices(r#""componentType":5126,"count":3"#), "accessor 1"),
        (indices(r#""componentType":5125,"count":3"#), "accessor 1"),
        // A sparse accessor without a view asking for a billion zeros.
        (
            r#"[{"componentType":5126,"count":1000000000,"type":"VEC3","min":[-1,-1,-3],"max":[1,1,-3],
                "sparse":{"count":1,"indices":{"bufferView":1,"componentType":5123},"values":{"bufferView":0}}},
               {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]"#
                .to_string(),
            "accessor 0",
        ),
        // POSITION naming an accessor that does not exist.
        (r#"[]"#.to_string(), "does not exist"),
    ];
    for (accessors, expected) in cases {
        let path = gltf_scene(dir.path(), r#"[{"mesh":0}]"#, Some(&accessors), "tri.bin");
        let outcome = render(&path);
        assert_refused(&outcome, &path, 64);
        assert!(
            outcome.stderr.contains(expected),
            "{accessors}: {}",
            outcome.stderr
        );
    }
    // A view longer than its buffer.
    let path = gltf_scene(dir.path(), r#"[{"mesh":0}]"#, None, "tri.bin");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        r#""byteOffset":36,"byteLength":6"#,
        r#""byteOffset":36,"byteLength":600"#,
    );
    std::fs::write(&path, text).unwrap();
    let outcome = render(&path);
    assert_refused(&outcome, &path, 64);
    assert!(
        outcome.stderr.contains("buffer view 1"),
        "{}",
        outcome.stderr
    );
}

#[cfg(target_os = "linux")]
#[test]
fn glb_files_cut_short_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let json = br#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-1,-1,-3],"max":[1,1,-3]},
            {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
        "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
        "buffers":[{"byteLength":44}]}"#;
    let mut json = json.to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin = triangle_buffer();
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    let whole = dir.path().join("whole.glb");
    std::fs::write(&whole, &glb).unwrap();
    assert_eq!(render(&whole).code, Some(0));
    // Cut inside the binary chunk, at its header, inside the JSON, inside the header.
    let json_end = 20 + json.len();
    for cut in [glb.len() - 10, json_end + 4, json_end, 40, 10] {
        let path = dir.path().join(format!("cut{cut}.glb"));
        std::fs::write(&path, &glb[..cut]).unwrap();
        assert_refused(&render(&path), &path, 64);
    }
}

#[cfg(target_os = "linux")]
#[test]
fn gltf_buffers_and_images_that_are_not_files_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("folder.bin")).unwrap();
    let fifo = dir.path().join("pipe.bin");
    let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: `mkfifo` reads the NUL-terminated path it is given.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    for uri in ["/dev/zero", "/dev/urandom", "folder.bin", "pipe.bin"] {
        let path = gltf_scene(dir.path(), r#"[{"mesh":0}]"#, None, uri);
        let outcome = render(&path);
        assert_refused(&outcome, &path, 64);
        assert!(outcome.stderr.contains(uri), "{}", outcome.stderr);
    }
    // An image that is a device: a warning, and the surface renders untextured.
    let path = gltf_scene(dir.path(), r#"[{"mesh":0}]"#, None, "tri.bin");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        r#""buffers""#,
        r#""materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}],
           "textures":[{"source":0}],"images":[{"uri":"/dev/urandom"}],"buffers""#,
    );
    let text = text.replace(r#""indices":1}"#, r#""indices":1,"material":0}"#);
    std::fs::write(&path, text).unwrap();
    assert_warned(
        &render(&path),
        &[
            &path.display().to_string(),
            "/dev/urandom",
            "not a regular file",
        ],
        64,
    );
}

// ---------------------------------------------------------------------------------
// Geometry that was slow: huge polygons, piles of copies.

#[cfg(target_os = "linux")]
#[test]
fn faces_of_200000_corners_are_triangulated_and_rendered() {
    use std::f64::consts::TAU;
    use std::fmt::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let n = 200_000;
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    type Corner<'a> = Box<dyn FnMut(usize) -> (f64, f64) + 'a>;
    let shapes: [(&str, Corner); 4] = [
        (
            "convex",
            Box::new(|k| {
                (
                    (TAU * k as f64 / n as f64).cos(),
                    (TAU * k as f64 / n as f64).sin(),
                )
            }),
        ),
        (
            "star",
            Box::new(|k| {
                let (a, r) = (
                    TAU * k as f64 / n as f64,
                    if k % 2 == 0 { 1.0 } else { 0.5 },
                );
                (r * a.cos(), r * a.sin())
            }),
        ),
        ("random", Box::new(move |_| (random(), random()))),
        (
            "wound",
            Box::new(|k| {
                let a = TAU * 0.4 * k as f64 + 1e-6 * k as f64;
                (a.cos(), a.sin())
            }),
        ),
    ];
    for (name, mut corner) in shapes {
        let mut text = String::new();
        for k in 0..n {
            let (x, y) = corner(k);
            writeln!(text, "v {x:.6} {y:.6} -3").unwrap();
        }
        text.push('f');
        for k in 1..=n {
            write!(text, " {k}").unwrap();
        }
        text.push('\n');
        let path = dir.path().join(format!("{name}.obj"));
        std::fs::write(&path, text).unwrap();
        let outcome = render(&path);
        assert_eq!(outcome.code, Some(0), "{name}: {}", outcome.stderr);
        assert!(
            outcome.peak < 512 << 20,
            "{name}: {} MiB",
            outcome.peak >> 20
        );
    }
}

#[cfg(target_os = "linux")]
#[test]
fn two_hundred_thousand_copies_of_a_triangle_render_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("copies.obj");
    let mut text = String::from("v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\n");
    text.push_str(&"f 1 2 3\n".repeat(200_000));
    std::fs::write(&path, text).unwrap();
    assert_warned(&render(&path), &["skipped 199999 duplicate shapes"], 256);
}

#[cfg(target_os = "linux")]
#[test]
fn scenes_and_meshes_that_are_fifos_or_folders_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    // A FIFO no one writes to: opening it for reading would block forever.
    let fifo = dir.path().join("pipe.obj");
    let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: `mkfifo` reads the NUL-terminated path it is given.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    std::fs::create_dir(dir.path().join("folder.ply")).unwrap();
    for mesh in ["pipe.obj", "folder.ply"] {
        let scene = dir.path().join(format!("{mesh}.toml"));
        std::fs::write(&scene, format!("[[mesh]]\nfile = \"{mesh}\"\n")).unwrap();
        let outcome = render(&scene);
        assert_refused(&outcome, &scene, 64);
        assert!(outcome.stderr.contains(mesh), "{}", outcome.stderr);
        let path = dir.path().join(mesh);
        assert_refused(&render(&path), &path, 64);
    }
}
