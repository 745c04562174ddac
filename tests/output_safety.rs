//! Nothing is lost: the output is replaced only by a complete image, never left
//! half-written, and a failure, a refused place or Ctrl-C leaves the previous file as
//! it was and no temporary file behind.

mod support;

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use assert_cmd::Command;

/// A lit sphere; renders in milliseconds at the sizes used here.
const SPHERE: &str = "S 0 0 -3 1\nP 2 2 0 1 1 1\n";
/// What the output file holds before a run that must not replace it.
const PREVIOUS: &[u8] = b"the previous image";

/// A folder with `scene.obj` (holding `scene`) and `out.png` (holding [`PREVIOUS`]).
fn setup(scene: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("scene.obj");
    fs::write(&scene_path, scene).unwrap();
    let out = dir.path().join("out.png");
    fs::write(&out, PREVIOUS).unwrap();
    (dir, scene_path, out)
}

fn render(scene: &Path, out: &Path) -> Command {
    let mut cmd = Command::cargo_bin("raytracer").unwrap();
    cmd.arg("render")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .args(["--width", "40", "--height", "30", "-j", "1"]);
    cmd
}

/// The names in `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_render_replaces_the_previous_file_and_leaves_nothing_else() {
    let (dir, scene, out) = setup(SPHERE);
    render(&scene, &out).assert().success();
    let (width, height, rgb) = support::read_png(&out);
    assert_eq!((width, height), (40, 30));
    assert!(rgb.iter().any(|&b| b > 0));
    assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
}

#[cfg(unix)]
#[test]
fn a_replaced_file_keeps_its_permissions_and_a_new_one_is_world_readable() {
    use std::os::unix::fs::PermissionsExt;
    let (dir, scene, out) = setup(SPHERE);
    fs::set_permissions(&out, fs::Permissions::from_mode(0o640)).unwrap();
    render(&scene, &out).assert().success();
    let mode = |p: &Path| fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&out), 0o640);
    let fresh = dir.path().join("fresh.png");
    render(&scene, &fresh).assert().success();
    assert_eq!(mode(&fresh), 0o644);
}

#[test]
fn a_failed_render_leaves_the_previous_file_intact() {
    let (dir, scene, out) = setup("v 0 0 -1\nf 1 2 3\n");
    render(&scene, &out).assert().code(2).stderr(format!(
        "error: {}:2: face index 2 out of range (1 vertex defined)\n",
        scene.display()
    ));
    assert_eq!(fs::read(&out).unwrap(), PREVIOUS);
    assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
}

#[test]
fn a_missing_folder_is_refused_before_the_scene_is_read() {
    // The scene is broken too: the output is checked first, before any work.
    let (dir, scene, _) = setup("v 0 0 x\n");
    let out = dir.path().join("missing").join("out.png");
    render(&scene, &out).assert().code(2).stderr(format!(
        "error: cannot write {}: folder {} does not exist\n",
        out.display(),
        dir.path().join("missing").display()
    ));
    assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
}

#[test]
fn a_folder_or_the_scene_itself_is_refused_as_output() {
    let (dir, scene, _) = setup(SPHERE);
    render(&scene, dir.path()).assert().code(2).stderr(format!(
        "error: cannot write {}: is a folder, not a file\n",
        dir.path().display()
    ));
    render(&scene, &scene).assert().code(2).stderr(format!(
        "error: cannot write {}: it is the scene file\n",
        scene.display()
    ));
    assert_eq!(fs::read_to_string(&scene).unwrap(), SPHERE);
}

#[test]
fn a_read_only_file_is_not_replaced() {
    let (dir, scene, out) = setup(SPHERE);
    let mut permissions = fs::metadata(&out).unwrap().permissions();
    permissions.set_readonly(true);
    fs::set_permissions(&out, permissions).unwrap();
    render(&scene, &out).assert().code(2).stderr(format!(
        "error: cannot write {}: the file is read-only\n",
        out.display()
    ));
    assert_eq!(fs::read(&out).unwrap(), PREVIOUS);
    assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
}

/// A folder where files cannot be created: a read-only folder, or (where permissions
/// do not bind, as for root) `/sys`. `None` if neither works here.
#[cfg(unix)]
fn read_only_folder(scratch: &Path) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let folder = scratch.join("read-only");
    fs::create_dir(&folder).unwrap();
    fs::set_permissions(&folder, fs::Permissions::from_mode(0o555)).unwrap();
    let writable = |f: &Path| fs::write(f.join("probe"), b"").is_ok();
    if !writable(&folder) {
        return Some(folder);
    }
    let sys = PathBuf::from("/sys");
    (sys.is_dir() && !writable(&sys)).then_some(sys)
}

#[cfg(unix)]
#[test]
fn a_read_only_folder_is_refused() {
    let (dir, scene, _) = setup(SPHERE);
    let Some(folder) = read_only_folder(dir.path()) else {
        eprintln!("skipped: no read-only folder available");
        return;
    };
    let out = folder.join("out.png");
    let denied = io::Error::from_raw_os_error(13).to_string();
    render(&scene, &out)
        .assert()
        .code(2)
        .stderr(format!("error: cannot write {}: {denied}\n", out.display()));
    assert!(!out.exists());
}

/// Ctrl-C, sent as SIGINT to a child process.
#[cfg(unix)]
mod interrupt {
    use std::fs;
    use std::path::Path;
    use std::process::{Child, Command, Stdio};
    use std::thread::sleep;
    use std::time::{Duration, Instant};

    use super::{PREVIOUS, entries, setup};

    /// Longest wait for a child to react; only reached if the test fails.
    const PATIENCE: Duration = Duration::from_secs(120);

    fn spawn(scene: &Path, out: &Path, args: &[&str]) -> Child {
        Command::new(assert_cmd::cargo::cargo_bin("raytracer"))
            .arg("render")
            .arg(scene)
            .arg("-o")
            .arg(out)
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    }

    fn send_sigint(child: &Child) {
        let status = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success(), "kill -INT failed");
    }

    /// Waits for the child's exit code, killing it if it takes unreasonably long.
    fn exit_code(mut child: Child) -> (Option<i32>, String) {
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > PATIENCE {
                child.kill().unwrap();
                panic!("the render ignored SIGINT");
            }
            sleep(Duration::from_millis(10));
        }
        let output = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        (output.status.code(), stderr)
    }

    #[test]
    fn ctrl_c_during_a_render_keeps_the_previous_file() {
        // A million triangles on top of each other: every ray tests them all, so the
        // render lasts far longer than the wait before the signal.
        let face: String = " 2 3".repeat(500_000);
        let scene = format!("v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1{face}\nP 0 0 0 1 1 1\n");
        let (dir, scene, out) = setup(&scene);
        let child = spawn(
            &scene,
            &out,
            &["--width", "64", "--height", "64", "-j", "1"],
        );
        // Time to start and install the handler; the signal then lands while the
        // scene is read, built or rendered, all of which must end the same way.
        sleep(Duration::from_secs(1));
        send_sigint(&child);
        let (code, stderr) = exit_code(child);
        assert_eq!(code, Some(130), "stderr: {stderr}");
        assert!(stderr.contains("interrupted"), "stderr: {stderr}");
        assert_eq!(fs::read(&out).unwrap(), PREVIOUS);
        assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
    }

    #[test]
    fn ctrl_c_while_the_png_is_written_leaves_no_temporary_file() {
        // A noisy image (normals of a random triangle soup) takes a while to encode;
        // the signal is sent as soon as its temporary file appears.
        let mut scene = String::new();
        let mut state = 12345u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        for i in 0..300 {
            for _ in 0..3 {
                scene += &format!("v {} {} {}\n", random(), random(), random() - 3.0);
            }
            scene += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
        }
        // The encoding lasts ~0.1 s; should the image be complete before the signal
        // lands (a busy machine can delay this test that long), try again.
        for _attempt in 0..5 {
            let (dir, scene, out) = setup(&scene);
            let args = ["--width", "2048", "--height", "2048", "--mode", "normal"];
            let child = spawn(&scene, &out, &args);
            let temp_name = format!(".raytracer-{}-", child.id());
            let start = Instant::now();
            loop {
                let names = entries(dir.path());
                let writing = names
                    .iter()
                    .any(|n| n.starts_with(&temp_name) && n.ends_with(".png.tmp"));
                if writing || fs::read(&out).unwrap() != PREVIOUS {
                    break;
                }
                assert!(start.elapsed() < PATIENCE, "no temporary file appeared");
                sleep(Duration::from_millis(1));
            }
            send_sigint(&child);
            let (code, stderr) = exit_code(child);
            if code == Some(0) {
                continue;
            }
            assert_eq!(code, Some(130), "stderr: {stderr}");
            assert_eq!(fs::read(&out).unwrap(), PREVIOUS);
            assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
            return;
        }
        panic!("the image was always complete before the signal landed");
    }
}
