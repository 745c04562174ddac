//! Third-party decoders run on data from files (Draco meshes, Basis Universal
//! textures): a panic in one, on corrupt data its crate did not foresee, becomes an
//! error of the file being read, and its message is not printed, so that the user
//! sees one warning or error naming the file rather than a panic's report.

use std::cell::Cell;
use std::panic::{self, AssertUnwindSafe};
use std::sync::Once;

thread_local! {
    /// Whether this thread is inside [`catch_quietly`].
    static QUIET: Cell<bool> = const { Cell::new(false) };
}

/// `decode()`, or `None` if it panicked. The panic's message is kept from the panic
/// hook (the one in place before the first call, which every other panic still
/// reaches: only a panic inside this call, on this thread, is quiet).
pub fn catch_quietly<T>(decode: impl FnOnce() -> T) -> Option<T> {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if !QUIET.with(Cell::get) {
                previous(info);
            }
        }));
    });
    let was = QUIET.with(|quiet| quiet.replace(true));
    let result = panic::catch_unwind(AssertUnwindSafe(decode));
    QUIET.with(|quiet| quiet.set(was));
    result.ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_inside_is_none_and_the_value_comes_through() {
        assert_eq!(catch_quietly(|| 7), Some(7));
        let none: Option<()> = catch_quietly(|| panic!("corrupt data"));
        assert_eq!(none, None);
        // Outside again: the flag is back.
        assert!(!QUIET.with(Cell::get));
    }
}
