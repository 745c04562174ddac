//! Deterministic sample values: where in a pixel the camera rays go, and as many
//! further dimensions per camera ray as an integrator asks for.
//!
//! **Camera positions.** One sample goes through the pixel centre. With `n` samples the
//! pixel is cut into `n` cells of equal area and one sample is placed uniformly at
//! random in each (stratified, or "jittered", sampling; see *Physically Based
//! Rendering*, 4th ed., section 8.5). For a square `n = k * k` the cells are the usual
//! `k x k` grid. For other `n` the pixel is cut into `m = round(sqrt(n))` columns
//! holding `n / m` or `n / m + 1` cells each, every column as wide as its share of the
//! cells, so each cell still covers exactly `1 / n` of the pixel and is close to
//! square: every sample keeps the weight `1 / n`.
//!
//! **Further dimensions** ([`PixelSample`]): uniform values in `[0, 1)`, drawn as 1D
//! or 2D values in the order the integrator asks for them, independent of each other
//! and of the camera position. A path tracer takes, say, two per bounce for the BSDF,
//! two for the light and one for Russian roulette. Across a pixel's samples each draw
//! is stratified (a randomised van der Corput or Sobol pattern, as pbrt-v4's
//! `PaddedSobolSampler`), so a pixel's samples cover every draw evenly; with one sample
//! a pixel's values are plain hashes.
//!
//! **Lens positions** ([`PixelSample::lens`]): one uniform point in `[0, 1)^2` per
//! camera ray for a thin lens, hashed apart from both of the above, so that a lens
//! changes none of an integrator's dimensions.
//!
//! Every value comes from hashes of the pixel index, the sample index and (for the
//! further dimensions) the dimension, not from a generator with state, as pbrt's
//! samplers seed from a hash of the pixel: every pixel is a pure function
//! of its position, so an image is identical from run to run and for any number of
//! threads, and a tile rendered alone equals the same pixels of the whole image.

use crate::math::{Float, ONE_BELOW_ONE, Vec2, Vec3};

/// Largest number of samples per pixel accepted.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 65_536;

/// Mixed into the hash of the camera positions so the pattern is not the plain hash of
/// small integers. Changing it, or the key it is mixed with, changes every
/// anti-aliased image.
const SEED: u64 = 0x5EED_A11A_5ED0_0001;

/// Mixed into the hash of the further dimensions, so that they are unrelated to the
/// camera positions.
const DIMENSION_SEED: u64 = 0xD1CE_5EED_0F0D_1235;

/// Mixed into the hash of the lens positions ([`PixelSample::lens`]), so that they are
/// unrelated to the camera positions and the further dimensions.
const LENS_SEED: u64 = 0x1E25_5EED_D15C_0003;

/// SplitMix64's increment, the golden ratio in 64 bits.
const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// The sample values of every pixel of an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSampler {
    /// Samples per pixel, at least 1.
    count: u32,
    /// Columns of strata: `round(sqrt(count))`, at least 1.
    columns: u32,
    /// Further dimensions each sample may draw (see [`PixelSample`]).
    dimensions: u32,
    /// Added to every hash key: [`crate::RenderOptions::seed`] times an odd
    /// constant, so seed 0 keeps the patterns of earlier versions.
    seed_offset: u64,
}

impl PixelSampler {
    /// A sampler taking `samples_per_pixel` samples in each pixel (at least one:
    /// 0 is taken as 1), each of which draws at most `dimensions` further dimensions
    /// (an integrator's [`crate::integrators::Integrator::dimensions`]).
    pub fn new(samples_per_pixel: u32, dimensions: u32) -> PixelSampler {
        let count = samples_per_pixel.max(1);
        let columns = ((count as f64).sqrt().round() as u32).clamp(1, count);
        PixelSampler {
            count,
            columns,
            dimensions,
            seed_offset: 0,
        }
    }

    /// The same sampler drawing another, equally valid, set of values for each
    /// `seed`; seed 0 changes nothing.
    pub fn with_seed(self, seed: u32) -> PixelSampler {
        PixelSampler {
            seed_offset: u64::from(seed).wrapping_mul(GOLDEN_GAMMA),
            ..self
        }
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
                .wrapping_add(sample as u64)
                .wrapping_add(self.seed_offset),
        );
        let x = column_start + jitter.x * column_width;
        let y = (row as Float + jitter.y) / rows as Float;
        // Rounding could reach the next pixel's edge; stay inside this one.
        Vec2::new(x.min(ONE_BELOW_ONE), y.min(ONE_BELOW_ONE))
    }

    /// The further dimensions of sample `sample` (`0..count`) of the pixel with index
    /// `pixel_index` (`row * width + column`), starting at dimension 0.
    #[inline]
    pub fn sample(&self, pixel_index: u64, sample: u32) -> PixelSample {
        debug_assert!(sample < self.count);
        let pixel = mix64(pixel_index ^ DIMENSION_SEED);
        PixelSample {
            pixel: mix64(pixel.wrapping_add(self.seed_offset) ^ DIMENSION_SEED),
            reversed_index: sample.reverse_bits(),
            index_digits: (self.count.next_power_of_two() - 1).reverse_bits(),
            independent_from: if self.count > 1 {
                STRATIFIED_DIMENSIONS
            } else {
                0
            },
            stream: mix64(
                pixel
                    .wrapping_add(sample as u64)
                    .wrapping_add(self.seed_offset),
            ),
            dimension: 0,
            #[cfg(debug_assertions)]
            declared: self.dimensions,
            pair: 0,
        }
    }

    /// The mean of `radiance(x, y, sample)` over the samples of pixel (`column`, `row`)
    /// of an image `width` pixels wide, with `x`, `y` image positions in pixels from
    /// the top-left corner and `sample` the sample's further dimensions. With one
    /// sample this is exactly `radiance(column + 0.5, row + 0.5, sample)`.
    #[inline]
    pub fn average(
        &self,
        column: u32,
        row: u32,
        width: u32,
        mut radiance: impl FnMut(Float, Float, &mut PixelSample) -> Vec3,
    ) -> Vec3 {
        let (x0, y0) = (column as Float, row as Float);
        let pixel_index = row as u64 * width as u64 + column as u64;
        if self.count == 1 {
            return radiance(x0 + 0.5, y0 + 0.5, &mut self.sample(pixel_index, 0));
        }
        let mut sum = Vec3::ZERO;
        for sample in 0..self.count {
            let offset = self.offset(pixel_index, sample);
            let mut values = self.sample(pixel_index, sample);
            sum += radiance(x0 + offset.x, y0 + offset.y, &mut values);
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

/// The further dimensions of one camera sample, drawn in order by an integrator.
///
/// With one sample per pixel, dimensions `2k` and `2k + 1` (from 0) are two 24-bit
/// fields of output `k` of a SplitMix64 generator seeded with a hash of the pixel
/// index: independent uniform values, computed directly from `k` rather than by
/// stepping. So are dimensions from [`STRATIFIED_DIMENSIONS`] on.
///
/// With `n > 1` samples the pixel's `n` samples share each draw's pattern, so that
/// together they cover it evenly, as pbrt-v4's `PaddedSobolSampler` does: a 1D draw
/// is the base-2 radical inverse (van der Corput) of the sample's index and a 2D draw
/// the first two dimensions of Sobol's sequence, a (0, 2)-sequence whose first `2^m`
/// points put exactly one point in every rectangle of area `2^-m` of the binary
/// grid; each draw of each pixel then randomises its pattern with its own hash: the
/// sample indices shuffled by an Owen scramble (Burley, "Practical Hash-based Owen
/// Scrambling", JCGT 2020), so that draws are independent of one another, and the
/// values XOR-ed with a random fraction (a digital shift), so that each is uniform;
/// both keep those properties. A light sample drawn this way lands on a small bright
/// light in as many of a pixel's samples as the light's share of the density says,
/// not in a random number of them: a white sphere in the studio at 64 samples has
/// 0.36x the noise of independent values (`render` at 160 x 120, the pixels' RMS
/// deviation from 4096 samples), with the environment's inversion sampling, for
/// 1.02x-1.04x the CPU time (the rough gold dragon, and the Lambertian Cornell box,
/// whose noise, mostly of later bounces, it leaves as it was).
///
/// Either way each value is a pure function of (pixel, sample, draw), however the
/// integrator interleaves its 1D and 2D draws, and nothing carries over between
/// pixels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PixelSample {
    /// A hash of the pixel index and the sampler's seed, that every draw of every
    /// sample of the pixel starts from.
    pixel: u64,
    /// The sample's index in its pixel, bit-reversed: the binary fraction
    /// whose digits the scrambles permute, so that no draw reverses bits.
    reversed_index: u32,
    /// The digits a bit-reversed sample index can have: the top `ceil(log2(n))`
    /// bits for `n` samples per pixel, none for one sample (independent values,
    /// from `stream`).
    index_digits: u32,
    /// The first dimension drawn as independent values: [`STRATIFIED_DIMENSIONS`]
    /// with several samples a pixel, 0 with one. (One comparison a draw: long
    /// Lambertian paths draw dozens of dimensions, most of them independent.)
    independent_from: u32,
    /// A hash of the pixel and sample indices: the independent values' generator
    /// seed, and the lens position's.
    stream: u64,
    /// The next dimension to draw.
    dimension: u32,
    /// How many dimensions the integrator said it draws; drawing more is a bug in
    /// the integrator (debug-asserted, kept in debug builds only), though the values
    /// stay well defined.
    #[cfg(debug_assertions)]
    declared: u32,
    /// When the next dimension is odd and independent: the generator output of its
    /// pair, drawn with the even dimension before it (or, after a stratified 2D draw
    /// that ends on the first independent dimension, by that draw).
    pair: u64,
}

/// Draws starting at this dimension or later take independent values even with
/// several samples a pixel: a path tracer's first two vertices (seven dimensions
/// each) and the light sample of its third. Stratification gains most where a
/// path's first vertices light a pixel; further down a path's dimensions are many
/// and the gain fades, while each stratified draw costs three scrambles and a hash
/// (every dimension stratified cost the rough gold dragon 1.07x-1.10x the CPU time of
/// independent values, these 1.02x-1.04x).
const STRATIFIED_DIMENSIONS: u32 = 16;

// Even, so that an independent pair's two dimensions are both independent or both not
// and a stratified 2D draw ends on the first independent dimension only from an odd
// start (`PixelSample::pair`).
const _: () = assert!(STRATIFIED_DIMENSIONS.is_multiple_of(2));

impl PixelSample {
    /// Takes the next `count` dimensions, returning the first's index.
    #[inline]
    fn take(&mut self, count: u32) -> u32 {
        #[cfg(debug_assertions)]
        assert!(
            self.dimension + count <= self.declared,
            "drew more than the {} dimensions the integrator declared",
            self.declared
        );
        let first = self.dimension;
        self.dimension += count;
        first
    }

    /// Dimension `dimension`'s hash: its shuffle seed in the low half, its
    /// scramble seed in the high half.
    #[inline]
    fn draw_hash(&self, dimension: u32) -> u64 {
        // `pixel` is a full hash already: one multiply and shift spread the
        // dimension over every bit (a second full mix measured slower).
        let h = (self.pixel ^ u64::from(dimension).wrapping_mul(GOLDEN_GAMMA))
            .wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^ (h >> 31)
    }

    /// The radical inverse (van der Corput value, as a 32-bit fraction) of the
    /// sample's index in a shuffle of the pixel's indices by `seed`, the shuffle
    /// being Burley's nested uniform scramble: `reverse(shuffled index)`, where the
    /// shuffled index is `reverse(lk(reverse(index)))` cut to the index's digits.
    /// Computed on the reversed index directly, so the two reversals cancel.
    #[inline]
    fn shuffled_radical_inverse(&self, seed: u32) -> u32 {
        laine_karras_permutation(self.reversed_index, seed) & self.index_digits
    }

    /// Dimension `dimension`'s independent value, the next one drawn: a 24-bit
    /// field of output `dimension / 2` of the sample's SplitMix64 generator, made
    /// at the pair's even dimension and kept for its odd one (long paths draw
    /// hundreds), as the sampler before stratification did.
    #[inline]
    fn independent(&mut self, dimension: u32) -> Float {
        unit(if dimension & 1 == 0 {
            self.pair = self.pair_output(dimension >> 1);
            self.pair >> 40
        } else {
            self.pair >> 8
        })
    }

    /// Output `pair` of the sample's SplitMix64 generator.
    #[inline]
    fn pair_output(&self, pair: u32) -> u64 {
        mix64(
            self.stream
                .wrapping_add(u64::from(pair).wrapping_mul(GOLDEN_GAMMA)),
        )
    }

    /// The next dimension: a uniform value in `[0, 1)`.
    #[inline]
    pub fn next_1d(&mut self) -> Float {
        let dimension = self.take(1);
        if dimension >= self.independent_from {
            return self.independent(dimension);
        }
        let hash = self.draw_hash(dimension);
        // The radical inverse, digitally shifted.
        unit_u32(self.shuffled_radical_inverse(hash as u32) ^ (hash >> 32) as u32)
    }

    /// Passes over the next dimension as [`PixelSample::next_1d`] would draw it,
    /// without making its value: every later draw is what it would have been. For a
    /// draw whose value would not be read (a stratified one costs a hash and a
    /// scramble). An independent even dimension still makes its pair's output, which
    /// the odd dimension after it reads.
    #[inline]
    pub fn skip_1d(&mut self) {
        let dimension = self.take(1);
        if dimension >= self.independent_from && dimension & 1 == 0 {
            self.pair = self.pair_output(dimension >> 1);
        }
    }

    /// The next two dimensions: a uniform point in `[0, 1)^2`.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let dimension = self.take(2);
        if dimension >= self.independent_from {
            if dimension & 1 == 0 {
                // Both halves of one pair's output (the next dimension makes its own).
                let pair = self.pair_output(dimension >> 1);
                return Vec2::new(unit(pair >> 40), unit(pair >> 8));
            }
            return Vec2::new(self.independent(dimension), self.independent(dimension + 1));
        }
        if dimension + 1 == self.independent_from {
            // This draw ends on the first independent dimension (even: 16), whose
            // pair's odd dimension, drawn next, reads the pair's output.
            self.pair = self.pair_output(self.independent_from >> 1);
        }
        sobol_2d(self, self.draw_hash(dimension))
    }

    /// Where on a thin lens this camera sample's ray starts: a uniform point in
    /// `[0, 1)^2`, a pure function of the pixel and sample (and seed) like the rest,
    /// hashed apart from the further dimensions, so it draws none of them: an
    /// integrator's dimensions are the same with and without a lens, and the lens
    /// value is independent of them and of the position in the pixel. With several
    /// samples a pixel's lens positions are a 2D draw of their own.
    #[inline]
    pub fn lens(&self) -> Vec2 {
        let h = mix64(mix64(self.stream) ^ LENS_SEED);
        if self.index_digits == 0 {
            return Vec2::new(unit(h >> 40), unit(h >> 8));
        }
        sobol_2d(self, mix64(self.pixel ^ LENS_SEED))
    }
}

/// The sample's point of Sobol's first two dimensions, its index shuffled by
/// `hash`'s low half and its coordinates digitally shifted (XOR-ed with random
/// fractions) by its high half and a second mix of it.
#[inline]
fn sobol_2d(sample: &PixelSample, hash: u64) -> Vec2 {
    let radical_inverse = sample.shuffled_radical_inverse(hash as u32);
    let shift_y = ((hash ^ (hash >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9) >> 32) as u32;
    let x = radical_inverse ^ (hash >> 32) as u32;
    let y = sobol_second_dimension(radical_inverse) ^ shift_y;
    Vec2::new(unit_u32(x), unit_u32(y))
}

/// Point `index` of the second dimension of Sobol's sequence, as 32 bits of a
/// fraction, from `radical_inverse`, the index's bits reversed (the index being
/// below `2^16`, as sample indices are: the low half is 0): the XOR of the direction
/// numbers of the index's set bits, a table lookup a byte (a loop over the bits
/// mispredicted its exit).
#[inline]
fn sobol_second_dimension(radical_inverse: u32) -> u32 {
    debug_assert!(radical_inverse & 0xFFFF == 0);
    SOBOL_SECOND[0][(radical_inverse >> 24) as usize]
        ^ SOBOL_SECOND[1][((radical_inverse >> 16) & 0xFF) as usize]
}

/// For the top and then the next byte of an index's radical inverse (the index's
/// low byte reversed, then its high byte reversed) and each value of it, the XOR of
/// the direction numbers of Sobol's second dimension for the index's set bits:
/// `v_1 = 1/2`, `v_{k+1} = v_k ^ (v_k / 2)` as 32-bit fractions.
static SOBOL_SECOND: [[u32; 256]; 2] = {
    let mut directions = [0u32; 16];
    let mut direction = 1u32 << 31;
    let mut bit = 0;
    while bit < 16 {
        directions[bit] = direction;
        direction ^= direction >> 1;
        bit += 1;
    }
    let mut table = [[0u32; 256]; 2];
    let mut byte = 0;
    while byte < 2 {
        let mut value = 0;
        while value < 256 {
            let mut xor = 0;
            let mut bit = 0;
            while bit < 8 {
                // Bit `bit` of this byte of the radical inverse is the index's bit
                // `7 - bit` of its byte.
                if value & (1 << bit) != 0 {
                    xor ^= directions[8 * byte + 7 - bit];
                }
                bit += 1;
            }
            table[byte][value] = xor;
            value += 1;
        }
        byte += 1;
    }
    table
};

/// Laine and Karras's hash-based permutation, with Burley's constants: each output
/// bit depends on the input's bits at and below it alone, so that on bit-reversed
/// values it is an Owen scramble (each digit flipped by a hash of the digits before
/// it), and on indices a permutation of every aligned power-of-two block. Burley's
/// nested uniform scramble of a fraction `x` is
/// `laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()`.
#[inline]
fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// The top 24 bits of the binary fraction `x` as a number in `[0, 1)`.
#[inline]
fn unit_u32(x: u32) -> Float {
    unit(u64::from(x >> 8))
}

/// The low 24 bits of `bits` as a number in `[0, 1)`: exactly what an `f32` in
/// `[0, 1)` can hold.
#[inline]
fn unit(bits: u64) -> Float {
    (bits & 0xFF_FFFF) as Float / (1u32 << 24) as Float
}

/// Two uniform numbers in `[0, 1)` from one 64-bit hash of `key`.
#[inline]
fn jitter(key: u64) -> Vec2 {
    let h = mix64(key ^ SEED);
    Vec2::new(unit(h >> 40), unit(h >> 8))
}

/// The SplitMix64 finalizer (Steele, Lea and Flood, "Fast splittable pseudorandom
/// number generators", OOPSLA 2014): a bijection on `u64` whose output bits each
/// depend on every input bit, so consecutive keys give unrelated numbers.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(GOLDEN_GAMMA);
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
        let sampler = PixelSampler::new(1, 0);
        assert_eq!(sampler.offset(12345, 0), Vec2::splat(0.5));
        let got = sampler.average(3, 7, 10, |x, y, _| Vec3::new(x, y, 1.0));
        assert_eq!(got, Vec3::new(3.5, 7.5, 1.0));
    }

    #[test]
    fn every_cell_holds_exactly_one_sample_for_any_count() {
        for count in [2, 3, 4, 5, 7, 8, 9, 10, 16, 17, 24, 64, 100] {
            let sampler = PixelSampler::new(count, 0);
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
            let sampler = PixelSampler::new(count, 0);
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
        let sampler = PixelSampler::new(16, 0);
        let a: Vec<Vec2> = (0..16).map(|s| sampler.offset(42, s)).collect();
        let b: Vec<Vec2> = (0..16).map(|s| sampler.offset(42, s)).collect();
        let c: Vec<Vec2> = (0..16).map(|s| sampler.offset(43, s)).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn the_average_of_a_linear_function_is_near_its_value_at_the_centre() {
        // Stratified samples of f(x, y) = x + 2y average close to f at the centre.
        let sampler = PixelSampler::new(64, 0);
        let got = sampler.average(0, 0, 1, |x, y, _| Vec3::splat(x + 2.0 * y));
        assert!((got.x - 1.5).abs() < 0.05, "got {}", got.x);
    }

    /// FNV-1a over the bits of every camera offset of a few pixels.
    fn offsets_checksum(count: u32) -> u64 {
        let sampler = PixelSampler::new(count, 0);
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for pixel in [0u64, 1, 2, 479, 480, 172_799, 1 << 20, u32::MAX as u64] {
            for sample in 0..count {
                let p = sampler.offset(pixel, sample);
                for bits in [p.x.to_bits(), p.y.to_bits()] {
                    h = (h ^ bits as u64).wrapping_mul(0x0100_0000_01b3);
                }
            }
        }
        h
    }

    #[test]
    fn camera_offsets_are_those_the_images_were_made_with() {
        // Bit for bit the positions of every anti-aliased image rendered so far (the
        // README's gallery uses 16 samples): adding dimensions must not move them.
        let sampler = PixelSampler::new(16, 5);
        assert_eq!(
            sampler.offset(12345, 7),
            Vec2::new(0.382_573_7, 0.780_575_34)
        );
        assert_eq!(offsets_checksum(2), 0xbc29_0e4c_95cf_0bf2);
        assert_eq!(offsets_checksum(5), 0x4909_a33a_14a3_f266);
        assert_eq!(offsets_checksum(16), 0x6953_b902_ee12_82e7);
    }

    /// The first `n` dimensions of sample `sample` of pixel `pixel`.
    fn draw(sampler: &PixelSampler, pixel: u64, sample: u32, n: u32) -> Vec<Float> {
        let mut dimensions = sampler.sample(pixel, sample);
        (0..n).map(|_| dimensions.next_1d()).collect()
    }

    #[test]
    fn dimensions_are_a_pure_function_of_pixel_sample_and_dimension() {
        let sampler = PixelSampler::new(4, 6);
        let a = draw(&sampler, 1000, 2, 6);
        // Another sampler, after other pixels drew theirs: nothing carries over.
        let other = PixelSampler::new(4, 6);
        for pixel in 0..100 {
            draw(&other, pixel, 1, 6);
        }
        assert_eq!(draw(&other, 1000, 2, 6), a);
        // A draw's values depend on the draws before it only through its first
        // dimension: a 2D draw after a 1D one, then another 1D draw.
        let mixed = |sampler: &PixelSampler| {
            let mut values = sampler.sample(1000, 2);
            let (x, p, y) = (values.next_1d(), values.next_2d(), values.next_1d());
            [x, p.x, p.y, y]
        };
        assert_eq!(mixed(&sampler), mixed(&other));
        assert_eq!(mixed(&sampler)[0], a[0]);
        assert_eq!(mixed(&sampler)[3], a[3]);
        // Pixels, samples and dimensions all give different values.
        assert_ne!(draw(&sampler, 1001, 2, 6), a);
        assert_ne!(draw(&sampler, 1000, 3, 6), a);
        let mut sorted = a.clone();
        sorted.sort_by(Float::total_cmp);
        sorted.dedup();
        assert_eq!(sorted.len(), a.len(), "{a:?}");
    }

    #[test]
    fn dimensions_are_uniform_and_uncorrelated() {
        // 64 pixels x 16 samples x 8 dimensions = 8192 values per dimension pair.
        let sampler = PixelSampler::new(16, 8);
        let mut bins = [0u32; 16];
        let (mut n, mut sum, mut sum_sq) = (0.0f64, 0.0f64, 0.0f64);
        let (mut products, mut camera_products) = (0.0f64, 0.0f64);
        for pixel in 0..64 {
            for sample in 0..16 {
                let values = draw(&sampler, pixel, sample, 8);
                let camera = sampler.offset(pixel, sample);
                for (d, &v) in values.iter().enumerate() {
                    assert!((0.0..1.0).contains(&v), "{v}");
                    bins[(v * 16.0) as usize] += 1;
                    let v = v as f64;
                    (n, sum, sum_sq) = (n + 1.0, sum + v, sum_sq + v * v);
                    if d > 0 {
                        products += (v - 0.5) * (values[d - 1] as f64 - 0.5);
                    }
                }
                camera_products += (values[0] as f64 - 0.5) * (camera.x as f64 - 0.5);
            }
        }
        let mean = sum / n;
        let variance = sum_sq / n - mean * mean;
        assert!((mean - 0.5).abs() < 0.01, "mean {mean}");
        assert!((variance - 1.0 / 12.0).abs() < 0.003, "variance {variance}");
        let expected = n / 16.0;
        for (i, &count) in bins.iter().enumerate() {
            let off = (count as f64 - expected).abs() / expected;
            assert!(off < 0.1, "bin {i}: {count} of {expected}");
        }
        // Correlation coefficients (covariance over variance 1/12), 1/sqrt(7168) and
        // 1/sqrt(1024) standard deviation: about 0.012 and 0.031.
        let next = products / (n * 7.0 / 8.0) * 12.0;
        let with_camera = camera_products / 1024.0 * 12.0;
        assert!(next.abs() < 0.05, "consecutive dimensions: {next}");
        assert!(
            with_camera.abs() < 0.12,
            "camera and dimension 0: {with_camera}"
        );
    }

    /// Whether `values` (in `[0, 1)`) put at most one value in each of `2^bits`
    /// equal intervals.
    fn one_per_interval(values: impl Iterator<Item = Float>, bits: u32) -> bool {
        let mut seen = vec![false; 1 << bits];
        values.into_iter().all(|v| {
            let cell = (v * (1 << bits) as Float) as usize;
            !std::mem::replace(&mut seen[cell], true)
        })
    }

    #[test]
    fn a_pixels_samples_cover_every_draw_evenly() {
        // 64 samples: each 1D draw puts one value in each sixty-fourth of [0, 1), and
        // each 2D draw one point in each rectangle of area 1/64 of the binary grid
        // (1 x 1/64, 1/2 x 1/32, ..., 1/64 x 1), in every pixel; so does the lens.
        let sampler = PixelSampler::new(64, 12);
        for pixel in [0u64, 1, 77, 1 << 30] {
            let draws: Vec<Vec<Float>> = (0..64)
                .map(|s| {
                    let mut values = sampler.sample(pixel, s);
                    let (a, b, c) = (values.next_1d(), values.next_2d(), values.next_1d());
                    let (d, e) = (values.next_2d(), values.next_2d());
                    let lens = values.lens();
                    vec![a, b.x, b.y, c, d.x, d.y, e.x, e.y, lens.x, lens.y]
                })
                .collect();
            for dimension in [0, 3] {
                assert!(one_per_interval(draws.iter().map(|v| v[dimension]), 6));
            }
            for x in [1, 4, 6, 8] {
                for x_bits in 0..=6 {
                    let cells: Vec<Float> = draws
                        .iter()
                        .map(|v| {
                            let column = (v[x] * (1 << x_bits) as Float).floor();
                            let row = (v[x + 1] * (1 << (6 - x_bits)) as Float).floor();
                            (column * (1 << (6 - x_bits)) as Float + row) / 64.0
                        })
                        .collect();
                    assert!(
                        one_per_interval(cells.into_iter(), 6),
                        "pixel {pixel}, draw at {x}, {x_bits} bits of x"
                    );
                }
            }
        }
        // Any other count: at most one value in each of the next power of two's
        // intervals.
        let sampler = PixelSampler::new(100, 1);
        let values = (0..100).map(|s| sampler.sample(5, s).next_1d());
        assert!(one_per_interval(values, 7));
        // One sample: independent values, different in every pixel.
        let one = PixelSampler::new(1, 2);
        let firsts: Vec<Float> = (0..64).map(|p| one.sample(p, 0).next_1d()).collect();
        assert!(!one_per_interval(firsts.into_iter(), 6));
    }

    #[test]
    fn independent_dimensions_are_their_generator_outputs_however_drawn() {
        // Dimension `d` of a draw starting at 16 or later (at 0 or later with one
        // sample) is a field of output `d / 2` of the sample's generator whatever mix
        // of 1D and 2D draws reaches it: after a 2D draw from 15, which ends on
        // dimension 16 (stratified) and leaves 17 to read its pair's output; after a
        // 1D draw at 16; 2D draws from odd and even dimensions.
        let expected = |values: &PixelSample, d: u32| {
            let output = values.pair_output(d / 2);
            unit(if d.is_multiple_of(2) {
                output >> 40
            } else {
                output >> 8
            })
        };
        let patterns: [&[u32]; 4] = [&[1, 2, 1, 2, 1], &[2, 1], &[1, 1, 2], &[2, 2, 1]];
        for (count, first_independent) in [(64, 16), (5, 16), (1, 0)] {
            let sampler = PixelSampler::new(count, 40);
            for pattern in patterns {
                for start in 0..3 {
                    let mut values = sampler.sample(77, count - 1);
                    // Each value with the first dimension of its draw.
                    let mut drawn: Vec<(Float, usize)> = vec![];
                    (0..start).for_each(|d| drawn.push((values.next_1d(), d)));
                    for &width in pattern.iter().cycle() {
                        let d = drawn.len();
                        if d + 2 > 40 {
                            break;
                        }
                        match width {
                            1 => drawn.push((values.next_1d(), d)),
                            _ => drawn.extend(values.next_2d().to_array().map(|v| (v, d))),
                        }
                    }
                    for (d, &(value, draw)) in drawn.iter().enumerate() {
                        if draw >= first_independent {
                            let d = d as u32;
                            assert_eq!(value, expected(&values, d), "{count} spp, dimension {d}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_skipped_dimension_leaves_every_later_draw_as_drawing_it_does() {
        // Skipping dimension `k` and then drawing on, in 1D or 2D draws from odd and
        // even dimensions, across the first independent dimension and with one
        // sample (all independent), gives what drawing every dimension gives.
        for count in [64, 5, 1] {
            let sampler = PixelSampler::new(count, 40);
            for skipped in 0..36 {
                for width in [1, 2] {
                    let rest = |values: &mut PixelSample| -> Vec<Float> {
                        let mut drawn = vec![];
                        for _ in 0..2 {
                            match width {
                                1 => drawn.push(values.next_1d()),
                                _ => drawn.extend(values.next_2d().to_array()),
                            }
                        }
                        drawn.push(values.next_1d());
                        drawn
                    };
                    let mut drawn = sampler.sample(77, count - 1);
                    let mut skipping = drawn.clone();
                    (0..skipped).for_each(|_| {
                        drawn.next_1d();
                        skipping.next_1d();
                    });
                    drawn.next_1d();
                    skipping.skip_1d();
                    assert_eq!(
                        rest(&mut skipping),
                        rest(&mut drawn),
                        "{count} spp, dimension {skipped} skipped, then {width}D draws"
                    );
                }
            }
        }
    }

    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "drew more than the 2 dimensions")]
    fn drawing_more_dimensions_than_declared_is_caught_in_debug_builds() {
        let mut dimensions = PixelSampler::new(1, 2).sample(0, 0);
        dimensions.next_2d();
        dimensions.next_1d();
    }
}
