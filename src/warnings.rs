//! Warnings as the user reads them: one line per kind.
//!
//! A reader warns once per thing it skips or replaces, and some things come by the
//! dozen: every material of a model whose `Kd + Ks` exceeds 1 in path mode, every
//! unused material in `raytracer info`, every `usemtl` of a different missing name.
//! Printed one by one they bury the warning that matters; [`coalesce`] keeps the
//! first of each kind and says how many more there were.

/// `warnings` with those of one kind after the first folded into it: the first's
/// text, then `(and N more like it)`. Two warnings are of one kind when they differ
/// only in quoted names (`'...'`) and numbers (line numbers, counts). The kinds keep
/// the order of their first warnings; a warning alone is unchanged.
pub fn coalesce<S: AsRef<str>>(warnings: &[S]) -> Vec<String> {
    let mut kinds: Vec<(String, &str, usize)> = Vec::new();
    for warning in warnings {
        let warning = warning.as_ref();
        let key = kind(warning);
        match kinds.iter_mut().find(|(k, _, _)| *k == key) {
            Some((_, _, count)) => *count += 1,
            None => kinds.push((key, warning, 1)),
        }
    }
    kinds
        .into_iter()
        .map(|(_, first, count)| match count {
            1 => first.to_string(),
            n => format!("{first} (and {} more like it)", n - 1),
        })
        .collect()
}

/// The text that warnings of one kind share: quoted names emptied, every run of
/// digits made `#`.
fn kind(warning: &str) -> String {
    let mut key = String::with_capacity(warning.len());
    let mut quoted = false;
    let mut in_digits = false;
    for c in warning.chars() {
        if c == '\'' {
            // A quote opens a name only after a space or a bracket (`'Ns'`, `('P'`);
            // an apostrophe inside a word (`file's`) is text.
            let opens = !quoted && key.chars().last().is_none_or(|p| " (:".contains(p));
            if opens || quoted {
                quoted = !quoted;
                key.push(c);
                in_digits = false;
                continue;
            }
        }
        if quoted {
            continue;
        }
        if c.is_ascii_digit() {
            if !in_digits {
                key.push('#');
            }
            in_digits = true;
            continue;
        }
        in_digits = false;
        key.push(c);
    }
    key
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warnings_of_one_kind_become_one_line_with_a_count() {
        let warnings = [
            "material 'red': Kd + Ks exceeds 1, scaled down in path mode to conserve energy",
            "a.obj:3: unknown material 'x'; using the default material",
            "material 'blue': Kd + Ks exceeds 1, scaled down in path mode to conserve energy",
            "a.obj:17: unknown material 'y'; using the default material",
            "material 'green': Kd + Ks exceeds 1, scaled down in path mode to conserve energy",
            "skipped 3 degenerate (zero-area) triangles",
        ];
        assert_eq!(
            coalesce(&warnings),
            [
                "material 'red': Kd + Ks exceeds 1, scaled down in path mode to conserve energy (and 2 more like it)",
                "a.obj:3: unknown material 'x'; using the default material (and 1 more like it)",
                "skipped 3 degenerate (zero-area) triangles",
            ]
        );
    }

    #[test]
    fn warnings_of_different_kinds_stay_apart() {
        let warnings = [
            "the scene has no lights (no light sources, no emitting surfaces): path mode renders it black",
            "the scene's camera is odd",
            "b.mtl:2: 'Ns' below 0 read as 0 (4 lines)",
            "b.mtl:9: unknown option '-q' of 'map_Kd' ignored",
        ];
        assert_eq!(coalesce(&warnings), warnings);
        assert_eq!(coalesce::<&str>(&[]), Vec::<String>::new());
    }
}
