//! Confined file access (`formats::load_with` with `FileAccess::confined_to`), as a
//! scene shipped to Dask workers is read: no file outside the scene's folder is
//! opened, whatever the scene names; each refusal names the file and line that named
//! the path. Unconfined, the same loads list every file the scene reads.

use std::fs;
use std::path::{Path, PathBuf};

use raytracer::formats::{self, FileAccess};

/// A 2x2 PNG, red.
fn png() -> Vec<u8> {
    let mut bytes = Vec::new();
    let image = image::RgbImage::from_pixel(2, 2, image::Rgb([255, 0, 0]));
    image::DynamicImage::ImageRgb8(image)
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
    bytes
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";

/// `root/scene/` holding the scene, and files outside it in `root/`.
struct Layout {
    root: tempfile::TempDir,
}

impl Layout {
    fn new() -> Layout {
        let root = tempfile::tempdir().unwrap();
        fs::create_dir(root.path().join("scene")).unwrap();
        fs::write(root.path().join("outside.png"), png()).unwrap();
        fs::write(root.path().join("outside.mtl"), "newmtl m\nKd 1 0 0\n").unwrap();
        fs::write(
            root.path().join("outside.obj"),
            TRIANGLE.to_owned() + "f 1 2 3\n",
        )
        .unwrap();
        Layout { root }
    }

    fn scene(&self) -> PathBuf {
        self.root.path().join("scene")
    }

    fn write(&self, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
        let path = self.scene().join(name);
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, contents).unwrap();
        path
    }

    fn confined(&self) -> FileAccess {
        FileAccess::confined_to(&self.scene()).unwrap()
    }
}

fn message(result: Result<formats::LoadedScene, formats::SceneError>) -> String {
    result.expect_err("an error").to_string()
}

#[test]
fn a_library_outside_the_folder_is_an_error_of_the_line_naming_it() {
    let layout = Layout::new();
    let obj = layout.write(
        "a.obj",
        format!("{TRIANGLE}mtllib ../outside.mtl\nf 1 2 3\n"),
    );
    let access = layout.confined();
    let error = message(formats::load_with(&obj, &access));
    assert!(
        error.starts_with(&format!("{}:7:", obj.display())),
        "{error}"
    );
    assert!(error.contains("outside the scene's folder"), "{error}");
    assert_eq!(access.refused(), [layout.root.path().join("outside.mtl")]);
    // Not confined, the same scene reads the library.
    let loaded = formats::load(&obj).unwrap();
    assert!(loaded.description.materials.iter().any(|m| m.name == "m"));
}

#[test]
fn a_texture_outside_the_folder_is_a_warning_and_is_not_read() {
    let layout = Layout::new();
    let absolute = layout.root.path().join("outside.png");
    layout.write(
        "a.mtl",
        format!(
            "newmtl near\nmap_Kd ../outside.png\nnewmtl far\nmap_Kd {}\n",
            absolute.display()
        ),
    );
    let obj = layout.write(
        "a.obj",
        format!("{TRIANGLE}mtllib a.mtl\nusemtl near\nf 1/1 2/2 3/3\n"),
    );
    let access = layout.confined();
    let loaded = formats::load_with(&obj, &access).unwrap();
    assert!(
        loaded
            .description
            .materials
            .iter()
            .all(|m| m.maps.is_none())
    );
    let warnings = &loaded.description.warnings;
    for line in [2, 4] {
        let at = format!(
            "{}:{line}: cannot read texture",
            layout.scene().join("a.mtl").display()
        );
        assert!(
            warnings
                .iter()
                .any(|w| w.starts_with(&at) && w.contains("outside the scene's folder")),
            "{warnings:?}"
        );
    }
    assert_eq!(access.refused(), [absolute]);
    // Not confined, both maps are read.
    let loaded = formats::load(&obj).unwrap();
    assert!(
        loaded
            .description
            .materials
            .iter()
            .all(|m| m.maps.is_some())
    );
}

#[test]
fn meshes_and_gltf_buffers_outside_the_folder_are_errors() {
    let layout = Layout::new();
    let toml = layout.write("s.toml", "[[mesh]]\nfile = \"../outside.obj\"\n");
    let error = message(formats::load_with(&toml, &layout.confined()));
    assert!(error.contains(&format!("{}:2", toml.display())), "{error}");
    assert!(error.contains("outside the scene's folder"), "{error}");
    assert!(formats::load(&toml).is_ok());

    fs::write(layout.root.path().join("b.bin"), [0u8; 36]).unwrap();
    let gltf = layout.write(
        "m.gltf",
        r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"../b.bin","byteLength":36}]}"#,
    );
    let error = message(formats::load_with(&gltf, &layout.confined()));
    assert!(error.contains(&gltf.display().to_string()), "{error}");
    assert!(error.contains("outside the scene's folder"), "{error}");
    assert!(formats::load(&gltf).is_ok());
}

#[cfg(unix)]
#[test]
fn a_link_that_leaves_the_folder_is_refused() {
    let layout = Layout::new();
    std::os::unix::fs::symlink(
        layout.root.path().join("outside.mtl"),
        layout.scene().join("l.mtl"),
    )
    .unwrap();
    let obj = layout.write("a.obj", format!("{TRIANGLE}mtllib l.mtl\nf 1 2 3\n"));
    let error = message(formats::load_with(&obj, &layout.confined()));
    assert!(error.contains("outside the scene's folder"), "{error}");
}

#[test]
fn the_files_asked_for_are_the_files_the_scene_reads() {
    let layout = Layout::new();
    layout.write("textures/wood.png", png());
    layout.write("lib/a.mtl", "newmtl m\nmap_Kd ../textures/wood.png\n");
    layout.write(
        "mesh.obj",
        format!("{TRIANGLE}mtllib lib/a.mtl\nusemtl m\nf 1/1 2/2 3/3\n"),
    );
    let toml = layout.write("s.toml", "[[mesh]]\nfile = \"mesh.obj\"\n");
    let access = layout.confined();
    formats::load_with(&toml, &access).unwrap();
    let relative: Vec<PathBuf> = access
        .asked()
        .iter()
        .map(|p| p.strip_prefix(layout.scene()).unwrap().to_path_buf())
        .collect();
    let expected = ["s.toml", "mesh.obj", "lib/a.mtl", "textures/wood.png"].map(Path::new);
    assert_eq!(relative, expected);
    assert!(access.refused().is_empty());
}
