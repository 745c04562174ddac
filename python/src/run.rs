//! Renders that behave as Python calls do: interruptible by Ctrl-C, reporting
//! progress, never raising `PanicException`.
//!
//! The render runs on a thread of its own, in bands of rows ([`raytracer::render_tile`],
//! each bit-identical to the same rows of the whole image), while the calling thread
//! waits with the interpreter released and wakes every [`POLL`] to run Python's signal
//! handlers (`Python::check_signals`: Ctrl-C raises `KeyboardInterrupt` there) and the
//! progress callback. A raised exception stops the render thread at the end of its band:
//! bands are sized to take about [`BAND_TIME`], so the call returns within a second.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBool;
use raytracer::film::{Aov, AovPlanes, Outputs};
use raytracer::math::Vec3;
use raytracer::{Film, RenderOptions, Tile};

use crate::{Error, Loaded};

/// How often the waiting thread looks at signals and progress.
const POLL: Duration = Duration::from_millis(50);

/// How long a band of rows should take: short enough for Ctrl-C to stop the render
/// promptly, long enough that starting a band (the integrator's tables) costs little.
const BAND_TIME: f64 = 0.15;

/// What the caller asked to be told of progress: nothing, a tqdm bar, or a callable.
pub(crate) struct Progress<'py> {
    callback: Option<Bound<'py, PyAny>>,
    /// A bar made here, closed when the render ends.
    bar: bool,
}

impl<'py> Progress<'py> {
    /// `progress=`: `None` or `False` for nothing, `True` for a tqdm bar (tqdm must be
    /// installed), or a callable taking `(done, total)` in rows.
    pub(crate) fn of(value: Option<&Bound<'py, PyAny>>) -> PyResult<Progress<'py>> {
        let Some(value) = value.filter(|v| !v.is_none()) else {
            return Ok(Progress {
                callback: None,
                bar: false,
            });
        };
        if let Ok(flag) = value.cast::<PyBool>() {
            if !flag.is_true() {
                return Ok(Progress {
                    callback: None,
                    bar: false,
                });
            }
            let bar = value
                .py()
                .import("raytracer._progress")?
                .getattr("TqdmProgress")?
                .call0()?;
            return Ok(Progress {
                callback: Some(bar),
                bar: true,
            });
        }
        if !value.is_callable() {
            return Err(PyValueError::new_err(format!(
                "progress must be True (a tqdm bar), False, None or a callable taking (done, total), not {}",
                value.get_type().name()?
            )));
        }
        Ok(Progress {
            callback: Some(value.clone()),
            bar: false,
        })
    }

    fn report(&self, done: u32, total: u32) -> PyResult<()> {
        if let Some(callback) = &self.callback {
            callback.call1((done, total))?;
        }
        Ok(())
    }

    fn close(&self) -> PyResult<()> {
        match &self.callback {
            Some(bar) if self.bar => bar.call_method0("close").map(drop),
            _ => Ok(()),
        }
    }
}

/// Why the render thread stopped early.
enum Stopped {
    Failed(Error),
    Cancelled,
}

/// Renders the whole image `options` describe, or `tile` of it, as [`Loaded::render`]
/// does, in bands on a thread of its own; see the module's documentation.
pub(crate) fn render(
    py: Python<'_>,
    loaded: Arc<Loaded>,
    options: RenderOptions,
    tile: Option<Tile>,
    aovs: Vec<Aov>,
    progress: &Progress<'_>,
) -> PyResult<Outputs> {
    let region = match tile {
        Some(tile) => tile.check(&options).map_err(Error::Tile)?,
        None => Tile::whole(&options),
    };
    let cancel = Arc::new(AtomicBool::new(false));
    let rows_done = Arc::new(AtomicU32::new(0));
    let (sender, receiver) = mpsc::channel();
    let worker = {
        let (cancel, rows_done) = (Arc::clone(&cancel), Arc::clone(&rows_done));
        std::thread::Builder::new()
            .name("raytracer render".into())
            .spawn(move || {
                let film = render_bands(&loaded, &options, region, &aovs, &cancel, &rows_done);
                // The caller may have gone (an exception): nobody to tell.
                let _ = sender.send(film);
            })
            .map_err(|e| PyRuntimeError::new_err(format!("cannot start the render thread: {e}")))?
    };
    // The thread stops at the end of its band.
    let stop = || cancel.store(true, Ordering::Relaxed);
    let mut receiver = Some(receiver);
    let mut reported = None;
    let outcome = loop {
        let waiting = receiver.take().expect("kept between polls");
        let (got, waiting) = py.detach(move || (waiting.recv_timeout(POLL), waiting));
        receiver = Some(waiting);
        if let Err(interrupt) = py.check_signals() {
            stop();
            break Err(interrupt);
        }
        let done = rows_done.load(Ordering::Relaxed);
        if reported != Some(done) {
            reported = Some(done);
            if let Err(raised) = progress.report(done, region.height) {
                stop();
                break Err(raised);
            }
        }
        match got {
            Ok(Ok(film)) => break Ok(film),
            Ok(Err(Stopped::Failed(error))) => break Err(error.into()),
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            // Cancelled only by this loop, which has left by then.
            Ok(Err(Stopped::Cancelled)) | Err(mpsc::RecvTimeoutError::Disconnected) => {
                break Err(PyRuntimeError::new_err(
                    "the render failed (an internal error: a panic, reported above); \
                     please report it with the scene",
                ));
            }
        }
    };
    // Joined detached: an interrupted render ends its band first.
    let _ = py.detach(move || worker.join());
    let closed = progress.close();
    let film = outcome?;
    closed?;
    Ok(film)
}

/// `wanted` rows, at least `fewest`; a multiple of 4 above 4, so that full mode's 4x4
/// packets stay whole.
fn band_rows(wanted: u64, fewest: u32) -> u32 {
    let rows = wanted.clamp(u64::from(fewest), 1 << 20) as u32;
    if rows > 4 {
        rows.next_multiple_of(4)
    } else {
        rows
    }
}

/// Renders `region` band by band into one film, counting the rows done, until done or
/// `cancel` is set. Bands grow or shrink towards [`BAND_TIME`].
fn render_bands(
    loaded: &Loaded,
    options: &RenderOptions,
    region: Tile,
    aovs: &[Aov],
    cancel: &AtomicBool,
    rows_done: &AtomicU32,
) -> Result<Outputs, Stopped> {
    crate::test_gate("RAYTRACER_TEST_GATE_RENDER");
    let lit = loaded.lit_for(options);
    let scene = lit.as_deref().unwrap_or(&loaded.scene);
    let width = region.width as usize;
    let size = width * region.height as usize;
    // Made at the first band unless it is the whole region (see below).
    let mut whole: Option<(Vec<Vec3>, AovPlanes)> = None;
    // As many rows as threads (rows are what the pixel loop spreads over them), and
    // a first band of some 64k samples, before its time is known.
    let fewest = rayon::current_num_threads().clamp(1, 1024) as u32;
    let samples_per_row = u64::from(region.width) * u64::from(options.samples_per_pixel_in_mode());
    let mut rows = band_rows((1 << 16) / samples_per_row.max(1), fewest);
    let mut y = 0;
    while y < region.height {
        if cancel.load(Ordering::Relaxed) {
            return Err(Stopped::Cancelled);
        }
        let height = rows.min(region.height - y);
        let band = Tile {
            y: region.y + y,
            height,
            ..region
        };
        let started = Instant::now();
        let part = raytracer::render_tile_outputs(scene, options, band, aovs)
            .map_err(|e| Stopped::Failed(Error::Tile(e)))?;
        if height == region.height {
            // One band for the whole region (a small frame): its outputs are the
            // region's, without a copy into buffers of their own.
            rows_done.store(height, Ordering::Relaxed);
            return Ok(part);
        }
        let (pixels, planes) =
            whole.get_or_insert_with(|| (vec![Vec3::ZERO; size], AovPlanes::new(aovs, size)));
        let at = y as usize * width;
        pixels[at..at + part.film.pixels.len()].copy_from_slice(&part.film.pixels);
        copy_planes(planes, &part.aovs, at);
        y += height;
        rows_done.store(y, Ordering::Relaxed);
        let per_row = started.elapsed().as_secs_f64() / f64::from(height);
        let wanted = (BAND_TIME / per_row.max(1e-9)) as u64;
        rows = band_rows(wanted.min(u64::from(rows) * 4), fewest);
    }
    let (pixels, planes) = whole.unwrap_or_else(|| (Vec::new(), AovPlanes::new(aovs, 0)));
    Ok(Outputs {
        film: Film {
            width: region.width,
            height: region.height,
            pixels,
        },
        aovs: planes,
    })
}

/// A band's planes into the whole region's, from pixel `at` on.
fn copy_planes(whole: &mut AovPlanes, band: &AovPlanes, at: usize) {
    fn copy<T: Copy>(to: &mut Option<Vec<T>>, from: &Option<Vec<T>>, at: usize) {
        if let (Some(to), Some(from)) = (to, from) {
            to[at..at + from.len()].copy_from_slice(from);
        }
    }
    copy(&mut whole.depth, &band.depth, at);
    copy(&mut whole.normal, &band.normal, at);
    copy(&mut whole.albedo, &band.albedo, at);
    copy(&mut whole.alpha, &band.alpha, at);
    copy(&mut whole.object_id, &band.object_id, at);
    copy(&mut whole.material_id, &band.material_id, at);
}
