//! The render options' table (`raytracer::options::OPTIONS`) is what the Python stub
//! and the documentation say: each fails here when an option is added, renamed or
//! retyped in one place and not the other. (The table reaching every front end with
//! the same values and range errors is `tests/python/test_options_table.py`.)
//!
//! The option tables of `docs/cli.md` and `docs/scene-format.md` are made from the
//! table, between `<!-- options: NAME -->` and `<!-- end of options -->`; after a
//! change to `src/options/defs.rs`,
//! `REGENERATE_DOCS=1 cargo test --release --test integration options_table::`
//! writes them again.

use std::path::Path;

use raytracer::options::defs::{cli_table, markdown_table, python_stub, toml_table};

fn read(path: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_python_stub_declares_the_keywords_of_the_table_once() {
    let stub = read("python/raytracer/_raytracer.pyi");
    for (class, scene) in [("RenderKeywords", false), ("SceneKeywords", true)] {
        let expected = python_stub(class, scene);
        assert!(
            stub.contains(&expected),
            "python/raytracer/_raytracer.pyi lacks, or differs from, the table's\n{expected}"
        );
    }
    // Said once: no function lists an option keyword of its own.
    for def in &raytracer::options::OPTIONS {
        let declared = format!("{}: ", def.python);
        assert_eq!(
            stub.matches(&format!("    {declared}")).count()
                + stub.matches(&format!("        {declared}")).count(),
            1,
            "{} is declared more than once in the stub",
            def.python
        );
    }
}

#[test]
fn the_documentation_lists_every_option_as_the_table_does() {
    let docs = read("docs/options.md");
    let expected = markdown_table();
    assert!(
        docs.contains(&expected),
        "docs/options.md lacks, or differs from, the table's\n{expected}"
    );
}

/// The text between `<!-- options: NAME -->` and the next `<!-- end of options -->`
/// of `page`, and where it lies.
fn section(page: &str, name: &str) -> Option<std::ops::Range<usize>> {
    let start_marker = format!("<!-- options: {name} -->\n");
    let start = page.find(&start_marker)? + start_marker.len();
    let end = start + page[start..].find("<!-- end of options -->")?;
    Some(start..end)
}

#[test]
fn the_cli_and_scene_file_pages_show_the_tables_made_from_options() {
    let regenerate = std::env::var_os("REGENERATE_DOCS").is_some();
    let pages: [(&str, Vec<(&str, String)>); 2] = [
        ("docs/cli.md", vec![("flags", cli_table())]),
        (
            "docs/scene-format.md",
            ["camera", "render", "environment"]
                .into_iter()
                .map(|s| (s, toml_table(s)))
                .collect(),
        ),
    ];
    for (page, sections) in pages {
        let mut text = read(page);
        for (name, expected) in sections {
            let range = section(&text, name)
                .unwrap_or_else(|| panic!("{page} has no <!-- options: {name} --> section"));
            if regenerate {
                text.replace_range(range, &expected);
                continue;
            }
            assert!(
                text[range] == expected,
                "{page}'s {name} table differs from src/options/defs.rs's OPTIONS; \
                 REGENERATE_DOCS=1 cargo test --release --test integration options_table:: \
                 writes it again. Expected:\n{expected}"
            );
        }
        if regenerate {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(page);
            std::fs::write(path, text).unwrap();
        }
    }
}
