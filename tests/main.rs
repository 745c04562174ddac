//! Every integration test, in one binary: one link and one copy of the library's
//! generic code instead of one per file, which was most of the CI's build time on
//! two cores. Each file in this folder is a module here (`cargo test --release
//! --test integration cli::` runs one file's tests); `every_file_is_a_module` keeps
//! a new file from being silently left out (Cargo's `autotests` is off).

#[path = "support/fuzz_checks.rs"]
mod fuzz_checks;
mod support;

mod anisotropy;
mod arguments;
mod bvh;
mod cli;
mod cli_output;
mod confined;
mod degenerate;
mod environment;
mod errors_doc;
mod first_image;
mod forgiving;
mod fuzz_regressions;
mod geometry;
mod gltf;
mod gltf_compression;
mod gltf_extensions;
mod gltf_pose;
mod instancing;
mod integrators;
mod lights;
mod look;
mod malformed;
mod materials;
mod numerics;
mod options_table;
mod output;
mod output_safety;
mod outputs;
mod path;
mod pbr_materials;
mod properties;
mod reader;
mod readme;
mod real_files;
mod reference;
mod scene_files;
mod shapes;
mod tangents;
mod textures;
mod tiles;
mod vertex_colours;

/// Cargo no longer finds the test files by itself: a file missing from the list
/// above would compile into nothing and pass unseen.
#[test]
fn every_file_is_a_module() {
    let folder = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let this = include_str!("main.rs");
    for entry in std::fs::read_dir(&folder).unwrap() {
        let path = entry.unwrap().path();
        let (Some(stem), Some("rs")) = (
            path.file_stem().and_then(|s| s.to_str()),
            path.extension().and_then(|e| e.to_str()),
        ) else {
            continue;
        };
        // A file of its own binary is a `[[test]]` of Cargo.toml instead.
        let own_binary =
            include_str!("../Cargo.toml").contains(&format!("path = \"tests/{stem}.rs\""));
        if stem != "main" && !own_binary {
            assert!(
                this.contains(&format!("\nmod {stem};\n")),
                "tests/{stem}.rs is not declared in tests/main.rs"
            );
        }
    }
}
