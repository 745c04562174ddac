//! The render options' table (`raytracer::options::OPTIONS`) is what the Python stub
//! and the documentation say: each fails here when an option is added, renamed or
//! retyped in one place and not the other. (The table reaching every front end with
//! the same values and range errors is `tests/python/test_options_table.py`.)

use std::path::Path;

use raytracer::options::defs::{markdown_table, python_stub};

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
