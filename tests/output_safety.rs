//! Nothing is lost: the output is replaced only by a complete image, never left
//! half-written, and a failure, a refused place or Ctrl-C leaves the previous file as
//! it was and no temporary file behind.

use crate::support;

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
        "error: cannot write {}: is a directory\n",
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
    use std::io::{BufRead, BufReader};
    use std::path::Path;
    use std::process::{Child, ChildStderr, Command, Stdio};
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

    /// Waits until the child catches SIGINT (its handler is installed), as
    /// `/proc/PID/status` shows, instead of guessing how long a start takes.
    fn wait_for_handler(child: &Child) {
        let status = format!("/proc/{}/status", child.id());
        let start = Instant::now();
        loop {
            let caught = fs::read_to_string(&status).ok().and_then(|s| {
                let line = s.lines().find(|l| l.starts_with("SigCgt:"))?;
                u64::from_str_radix(line["SigCgt:".len()..].trim(), 16).ok()
            });
            // Bit 1 (SIGINT is signal 2).
            if caught.is_some_and(|mask| mask & 2 != 0) {
                return;
            }
            assert!(
                start.elapsed() < PATIENCE,
                "the handler was never installed"
            );
            sleep(Duration::from_millis(1));
        }
    }

    /// Spawns a render that pauses at `step` (`BEFORE_COMMIT` or `AFTER_COMMIT`, see
    /// `output::atomic::write_atomically`) and returns once it says it is paused there, with the
    /// rest of its stderr to read.
    fn spawn_paused(
        scene: &Path,
        out: &Path,
        step: &str,
    ) -> (Child, std::io::Lines<BufReader<ChildStderr>>) {
        let variable = format!("RAYTRACER_TEST_PAUSE_{step}");
        let mut child = Command::new(assert_cmd::cargo::cargo_bin("raytracer"))
            .arg("render")
            .arg(scene)
            .arg("-o")
            .arg(out)
            .args(["--width", "64", "--height", "48"])
            // Far longer than any test waits: only the signal ends the pause.
            .env(&variable, "600000")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        for line in lines.by_ref() {
            if line.unwrap().starts_with(&format!("{variable}: pausing")) {
                return (child, lines);
            }
        }
        let _ = child.kill();
        let status = child.wait();
        panic!("the render never reached {variable} ({status:?})");
    }

    /// The child's exit code and the rest of its stderr.
    fn finish(
        mut child: Child,
        lines: std::io::Lines<BufReader<ChildStderr>>,
    ) -> (Option<i32>, String) {
        let rest: Vec<String> = lines.map(Result::unwrap).collect();
        (child.wait().unwrap().code(), rest.join("\n"))
    }

    #[test]
    fn ctrl_c_during_a_render_keeps_the_previous_file() {
        // A million triangles on top of each other: every ray tests them all, so the
        // render lasts seconds, far longer than the signal takes to arrive.
        let face: String = " 2 3".repeat(500_000);
        let scene = format!("v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1{face}\nP 0 0 0 1 1 1\n");
        let (dir, scene, out) = setup(&scene);
        let child = spawn(
            &scene,
            &out,
            &["--width", "64", "--height", "64", "-j", "1"],
        );
        wait_for_handler(&child);
        send_sigint(&child);
        let (code, stderr) = exit_code(child);
        assert_eq!(code, Some(130), "stderr: {stderr}");
        assert!(stderr.contains("interrupted"), "stderr: {stderr}");
        assert_eq!(fs::read(&out).unwrap(), PREVIOUS);
        assert_eq!(entries(dir.path()), ["out.png", "scene.obj"]);
    }

    #[test]
    fn ctrl_c_before_the_rename_keeps_the_previous_file_and_no_temporary_file() {
        for name in ["out.png", "out.exr"] {
            let (dir, scene, _) = setup(super::SPHERE);
            let out = dir.path().join(name);
            fs::write(&out, PREVIOUS).unwrap();
            let (child, lines) = spawn_paused(&scene, &out, "BEFORE_COMMIT");
            // The complete temporary file waits beside the output.
            let temp_name = format!(".raytracer-{}-", child.id());
            assert!(
                entries(dir.path())
                    .iter()
                    .any(|n| n.starts_with(&temp_name)),
                "{:?}",
                entries(dir.path())
            );
            send_sigint(&child);
            let (code, stderr) = finish(child, lines);
            assert_eq!(code, Some(130), "stderr: {stderr}");
            assert!(
                stderr.contains(&format!("interrupted; {} left as it was", out.display())),
                "stderr: {stderr}"
            );
            assert_eq!(fs::read(&out).unwrap(), PREVIOUS, "{name}");
            let mut expected = vec![name, "out.png", "scene.obj"];
            expected.dedup();
            expected.sort();
            assert_eq!(entries(dir.path()), expected, "{name}");
        }
    }

    #[test]
    fn ctrl_c_after_the_rename_says_the_new_file_is_complete_and_exits_0() {
        for name in ["out.png", "out.exr"] {
            let (dir, scene, _) = setup(super::SPHERE);
            let out = dir.path().join(name);
            fs::write(&out, PREVIOUS).unwrap();
            let (child, lines) = spawn_paused(&scene, &out, "AFTER_COMMIT");
            send_sigint(&child);
            let (code, stderr) = finish(child, lines);
            assert_eq!(code, Some(0), "stderr: {stderr}");
            assert!(
                stderr.contains("holds the complete new image"),
                "stderr: {stderr}"
            );
            let written = fs::read(&out).unwrap();
            if name.ends_with(".png") {
                let (width, height, rgb) = super::support::read_png(&out);
                assert_eq!((width, height), (64, 48));
                assert!(rgb.iter().any(|&b| b > 0));
            } else {
                assert_eq!(&written[..4], &[0x76, 0x2f, 0x31, 0x01], "EXR magic number");
            }
            assert_eq!(
                entries(dir.path()).len(),
                if name == "out.png" { 2 } else { 3 }
            );
        }
    }
}
