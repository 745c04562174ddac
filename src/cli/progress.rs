//! Progress on stderr for the slow steps of a render. Nothing is drawn unless stderr
//! is a terminal, and nothing before a step has run for [`REVEAL_AFTER`]: quick
//! renders and scripts see no flicker and no control characters.

use std::io::IsTerminal;
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use indicatif::{FormattedDuration, ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};

/// How long a step runs before its progress appears.
const REVEAL_AFTER: Duration = Duration::from_millis(500);
/// Redraw interval once shown, so the elapsed time moves even between updates.
const TICK: Duration = Duration::from_millis(100);

/// One step's progress bar (with a length) or spinner (without). Cleared from the
/// terminal when dropped, also on early return with an error.
pub struct Progress {
    bar: ProgressBar,
    /// Tells the reveal thread the step is over; `None` when nothing is ever drawn.
    reveal: Option<(Sender<()>, JoinHandle<()>)>,
}

impl Progress {
    /// Starts timing a step called `label` of `total` units (`None` for a spinner).
    /// With `visible` false, or stderr not a terminal, nothing is ever drawn.
    pub fn start(label: &str, total: Option<u64>, visible: bool) -> Progress {
        Progress::with_rate(label, total, 0, visible)
    }

    /// [`Progress::start`] for rows of `samples_per_row` camera samples each, with
    /// the samples per second so far (none shown for 0).
    pub fn with_rate(
        label: &str,
        total: Option<u64>,
        samples_per_row: u64,
        visible: bool,
    ) -> Progress {
        let template = match (total, samples_per_row) {
            (Some(_), 0) => {
                "{msg} [{bar:40}] {pos}/{len} rows, {percent}%  elapsed {elapsed_precise}  ETA {average_eta}"
            }
            (Some(_), _) => {
                "{msg} [{bar:40}] {pos}/{len} rows, {percent}%  {samples_per_second}  elapsed {elapsed_precise}  ETA {average_eta}"
            }
            (None, _) => "{spinner} {msg}  elapsed {elapsed_precise}",
        };
        let rate = move |state: &ProgressState, out: &mut dyn std::fmt::Write| {
            let seconds = state.elapsed().as_secs_f64();
            if seconds > 0.0 {
                let per_second = (state.pos() * samples_per_row) as f64 / seconds;
                let _ = write!(out, "{:.2} M samples/s", per_second / 1e6);
            }
        };
        let style = ProgressStyle::with_template(template)
            .expect("the templates above are valid")
            .with_key("average_eta", average_eta)
            .with_key("samples_per_second", rate)
            .progress_chars("=> ");
        let bar = ProgressBar::with_draw_target(total, ProgressDrawTarget::hidden())
            .with_style(style)
            .with_message(label.to_string());
        if !visible || !std::io::stderr().is_terminal() {
            return Progress { bar, reveal: None };
        }
        let (done, wait) = mpsc::channel();
        let shown = bar.clone();
        // A thread rather than a check in `inc`, so that a step whose first unit
        // takes long still shows its elapsed time.
        let thread = thread::spawn(move || {
            if let Err(RecvTimeoutError::Timeout) = wait.recv_timeout(REVEAL_AFTER) {
                shown.set_draw_target(ProgressDrawTarget::stderr());
                shown.enable_steady_tick(TICK);
            }
        });
        Progress {
            bar,
            reveal: Some((done, thread)),
        }
    }

    /// Records one finished unit (a row): an atomic add, safe from any thread.
    pub fn inc(&self) {
        self.bar.inc(1);
    }
}

/// Time left at the average pace so far. indicatif's own `{eta}` follows the recent
/// pace, which misleads here: rows of empty sky finish in microseconds and rows
/// through a dense mesh take far longer, so the recent pace swings widely.
fn average_eta(state: &ProgressState, out: &mut dyn std::fmt::Write) {
    let (done, total) = (state.pos(), state.len().unwrap_or(0));
    if done == 0 || done >= total {
        let _ = write!(out, "--:--:--");
        return;
    }
    let left = state.elapsed().mul_f64((total - done) as f64 / done as f64);
    let _ = write!(out, "{}", FormattedDuration(left));
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Some((done, thread)) = self.reveal.take() {
            // The thread may have timed out already; then nobody listens, which is fine.
            let _ = done.send(());
            let _ = thread.join();
        }
        self.bar.finish_and_clear();
    }
}
