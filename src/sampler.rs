//! Where in a pixel the camera rays go: the pixel centre for one sample, stratified
//! jittered positions for more.
//!
//! With `n` samples the pixel is cut into `n` cells of equal area and one sample is
//! placed uniformly at random in each (stratified, or "jittered", sampling; see
//! *Physically Based Rendering*, 4th ed., section 8.5). For a square `n = k * k` the
//! cells are the usual `k x k` grid. For other `n` the pixel is cut into
//! `m = round(sqrt(n))` columns holding `n / m` or `n / m + 1` cells each, every column
//! as wide as its share of the cells, so each cell still covers exactly `1 / n` of the
//! pixel and is close to square: every sample keeps the weight `1 / n`.
//!
//! The random offsets come from a hash of the pixel index and the sample index, not
//! from a generator with state: every pixel is a pure function of its position, so an
//! image is identical from run to run and for any number of threads.

use crate::math::{Float, Vec2, Vec3};

/// Largest number of samples per pixel accepted.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 65_536;

/// Mixed into every hash so the sample pattern is not the plain hash of small integers.
const SEED: u64 = 0x5EED_A11A_5ED0_0001;

/// The sample positions of every pixel of an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSampler {
    /// Samples per pixel, at least 1.
    count: u32,
    /// Columns of strata: `round(sqrt(count))`, at least 1.
    columns: u32,
}

impl PixelSampler {
    /// A sampler taking `samples_per_pixel` samples in each pixel (at least one:
    /// 0 is taken as 1).
    pub fn new(samples_per_pixel: u32) -> PixelSampler {
        let count = samples_per_pixel.max(1);
        let columns = ((count as f64).sqrt().round() as u32).clamp(1, count);
        PixelSampler { count, columns }
    }

    /// Samples taken in each pixel.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Where sample `sample` (`0..count`) of the pixel with index `pixel_index`
    /// (`row * width + column`) lies, as an offset from the pixel's top-left corner
    /// in `[0, 1)` on both axes. With one sample this is the centre `(0.5, 0.5)`.
    #[inline]
    pub fn offset(&self, pixel_index: u64, sample: u32) -> Vec2 {
        debug_assert!(sample < self.count);
        if self.count == 1 {
            return Vec2::splat(0.5);
        }
        let (column_start, column_width, row, rows) = self.stratum(sample);
        let jitter = jitter(
            pixel_index
                .wrapping_mul(self.count as u64)
                .wrapping_add(sample as u64),
        );
        let x = column_start + jitter.x * column_width;
        let y = (row as Float + jitter.y) / rows as Float;
        // Rounding could reach the next pixel's edge; stay inside this one.
        Vec2::new(x.min(ONE_BELOW_ONE), y.min(ONE_BELOW_ONE))
    }

    /// The mean of `radiance(x, y)` over the samples of pixel (`column`, `row`) of an
    /// image `width` pixels wide, with `x`, `y` image positions in pixels from the
    /// top-left corner. With one sample this is exactly `radiance(column + 0.5, row + 0.5)`.
    #[inline]
    pub fn average(
        &self,
        column: u32,
        row: u32,
        width: u32,
        mut radiance: impl FnMut(Float, Float) -> Vec3,
    ) -> Vec3 {
        let (x0, y0) = (column as Float, row as Float);
        if self.count == 1 {
            return radiance(x0 + 0.5, y0 + 0.5);
        }
        let pixel_index = row as u64 * width as u64 + column as u64;
        let mut sum = Vec3::ZERO;
        for sample in 0..self.count {
            let offset = self.offset(pixel_index, sample);
            sum += radiance(x0 + offset.x, y0 + offset.y);
        }
        sum / self.count as Float
    }

    /// The cell of sample `sample`: its column's left edge and width, its row and the
    /// number of rows in its column. The first `count % columns` columns hold one
    /// cell more than the others.
    #[inline]
    fn stratum(&self, sample: u32) -> (Float, Float, u32, u32) {
        let per_column = self.count / self.columns;
        let taller = self.count % self.columns;
        let in_taller = taller * (per_column + 1);
        let (column, row, rows) = if sample < in_taller {
            let rows = per_column + 1;
            (sample / rows, sample % rows, rows)
        } else {
            let rest = sample - in_taller;
            (taller + rest / per_column, rest % per_column, per_column)
        };
        let cells_before = column * per_column + column.min(taller);
        let n = self.count as Float;
        (cells_before as Float / n, rows as Float / n, row, rows)
    }
}

/// The largest `f32` below 1.
const ONE_BELOW_ONE: Float = 1.0 - Float::EPSILON / 2.0;

/// Two uniform numbers in `[0, 1)` from one 64-bit hash of `key`.
#[inline]
fn jitter(key: u64) -> Vec2 {
    let h = mix64(key ^ SEED);
    // 24 bits each: exactly what an f32 in [0, 1) can hold.
    let to_unit = |bits: u64| (bits & 0xFF_FFFF) as Float / (1u32 << 24) as Float;
    Vec2::new(to_unit(h >> 40), to_unit(h >> 8))
}

/// The SplitMix64 finalizer (Steele, Lea and Flood, "Fast splittable pseudorandom
/// number generators", OOPSLA 2014): a bijection on `u64` whose output bits each
/// depend on every input bit, so consecutive keys give unrelated numbers.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Which cell of the `n`-cell layout `p` falls in, found from the position
    /// alone (not from the sample index), so the test checks the geometry.
    fn cell_of(sampler: &PixelSampler, p: Vec2) -> (u32, u32) {
        for sample in 0..sampler.count {
            let (x0, w, row, rows) = sampler.stratum(sample);
            let in_x = p.x >= x0 && p.x < x0 + w;
            let in_y =
                p.y >= row as Float / rows as Float && p.y < (row + 1) as Float / rows as Float;
            if in_x && in_y {
                return ((x0 * 1e6) as u32, row);
            }
        }
        panic!("{p} lies in no cell");
    }

    #[test]
    fn one_sample_is_the_pixel_centre() {
        let sampler = PixelSampler::new(1);
        assert_eq!(sampler.offset(12345, 0), Vec2::splat(0.5));
        let got = sampler.average(3, 7, 10, |x, y| Vec3::new(x, y, 1.0));
        assert_eq!(got, Vec3::new(3.5, 7.5, 1.0));
    }

    #[test]
    fn every_cell_holds_exactly_one_sample_for_any_count() {
        for count in [2, 3, 4, 5, 7, 8, 9, 10, 16, 17, 24, 64, 100] {
            let sampler = PixelSampler::new(count);
            for pixel in [0u64, 1, 999, 1 << 27] {
                let mut cells: Vec<(u32, u32)> = (0..count)
                    .map(|s| {
                        let p = sampler.offset(pixel, s);
                        assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                        cell_of(&sampler, p)
                    })
                    .collect();
                cells.sort_unstable();
                cells.dedup();
                assert_eq!(cells.len(), count as usize, "count {count}, pixel {pixel}");
            }
        }
    }

    #[test]
    fn cells_tile_the_pixel_with_equal_areas() {
        for count in [2, 3, 5, 6, 7, 11, 16, 23] {
            let sampler = PixelSampler::new(count);
            let mut area = 0.0;
            for sample in 0..count {
                let (_, w, _, rows) = sampler.stratum(sample);
                let cell = w / rows as Float;
                assert!((cell - 1.0 / count as Float).abs() < 1e-6, "count {count}");
                area += cell;
            }
            assert!((area - 1.0).abs() < 1e-5, "count {count}: area {area}");
        }
    }

    #[test]
    fn offsets_are_fixed_but_differ_between_pixels() {
        let sampler = PixelSampler::new(16);
        let a: Vec<Vec2> = (0..16).map(|s| sampler.offset(42, s)).collect();
        let b: Vec<Vec2> = (0..16).map(|s| sampler.offset(42, s)).collect();
        let c: Vec<Vec2> = (0..16).map(|s| sampler.offset(43, s)).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn the_average_of_a_linear_function_is_near_its_value_at_the_centre() {
        // Stratified samples of f(x, y) = x + 2y average close to f at the centre.
        let sampler = PixelSampler::new(64);
        let got = sampler.average(0, 0, 1, |x, y| Vec3::splat(x + 2.0 * y));
        assert!((got.x - 1.5).abs() < 0.05, "got {}", got.x);
    }
}
