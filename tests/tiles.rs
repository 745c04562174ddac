//! `render_tile`: any part of the image, bit-identical to the same pixels of the
//! whole render, and a clear error for a tile that is not inside the image.

use crate::support;

use raytracer::math::Vec3;
use raytracer::{Film, Mode, RenderOptions, Tile, TileError, render, render_tile};

use support::cornell_scene;

/// 37x23: odd sizes, so that edge tiles of a regular grid come out narrower.
fn cornell_options(mode: Mode, samples_per_pixel: u32) -> RenderOptions {
    support::cornell_options(37, 23, mode, samples_per_pixel)
}

/// The pixels of `tile` cut out of a whole film.
fn crop(film: &Film, tile: Tile) -> Vec<Vec3> {
    (tile.y..tile.y + tile.height)
        .flat_map(|row| {
            let start = (row * film.width + tile.x) as usize;
            film.pixels[start..start + tile.width as usize]
                .iter()
                .copied()
        })
        .collect()
}

/// Every tile of an 8x8 grid over the image: the last column and row are narrower.
fn grid(options: &RenderOptions) -> Vec<Tile> {
    let mut tiles = Vec::new();
    for y in (0..options.height).step_by(8) {
        for x in (0..options.width).step_by(8) {
            let (width, height) = (8.min(options.width - x), 8.min(options.height - y));
            tiles.push(Tile {
                x,
                y,
                width,
                height,
            });
        }
    }
    tiles
}

fn modes() -> [RenderOptions; 3] {
    [
        cornell_options(Mode::Full, 4),
        cornell_options(Mode::Depth, 1),
        cornell_options(Mode::Normal, 1),
    ]
}

#[test]
fn tiles_are_the_same_pixels_of_the_whole_render() {
    let scene = cornell_scene();
    for options in modes() {
        let whole = render(&scene, &options);
        let (w, h) = (options.width, options.height);
        let mut tiles = vec![
            Tile::whole(&options),
            Tile {
                x: 0,
                y: 0,
                width: 1,
                height: 1,
            },
            Tile {
                x: w - 1,
                y: h - 1,
                width: 1,
                height: 1,
            },
            Tile {
                x: 18,
                y: 11,
                width: 1,
                height: 1,
            },
            Tile {
                x: 0,
                y: h - 1,
                width: w,
                height: 1,
            },
            Tile {
                x: w - 1,
                y: 0,
                width: 1,
                height: h,
            },
            Tile {
                x: 5,
                y: 3,
                width: 20,
                height: 13,
            },
        ];
        tiles.extend(grid(&options));
        for tile in tiles {
            let film = render_tile(&scene, &options, tile).unwrap();
            assert_eq!((film.width, film.height), (tile.width, tile.height));
            // Exact equality: the same rays through the same code.
            assert_eq!(
                film.pixels,
                crop(&whole, tile),
                "{:?}: {tile}",
                options.mode
            );
        }
    }
}

#[test]
fn tiles_on_three_threads_make_the_image_of_one_thread() {
    let scene = cornell_scene();
    let pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    };
    for options in modes() {
        let whole = pool(1).install(|| render(&scene, &options));
        assert_eq!(pool(3).install(|| render(&scene, &options)), whole);
        // The grid's tiles, rendered on three threads, put back together.
        let mut assembled = Film {
            pixels: vec![Vec3::splat(-1.0); whole.pixels.len()],
            ..whole.clone()
        };
        for tile in grid(&options) {
            let film = pool(3).install(|| render_tile(&scene, &options, tile).unwrap());
            for (row, line) in film.pixels.chunks(tile.width as usize).enumerate() {
                let start = ((tile.y + row as u32) * whole.width + tile.x) as usize;
                assembled.pixels[start..start + line.len()].copy_from_slice(line);
            }
        }
        assert_eq!(assembled, whole, "{:?}", options.mode);
    }
}

#[test]
fn a_tile_not_inside_the_image_is_an_error() {
    let scene = cornell_scene();
    let options = cornell_options(Mode::Full, 1);
    let outside = |x, y, width, height| {
        let tile = Tile {
            x,
            y,
            width,
            height,
        };
        let err = render_tile(&scene, &options, tile).unwrap_err();
        assert_eq!(
            err,
            TileError::Outside {
                tile,
                width: 37,
                height: 23
            }
        );
        err.to_string()
    };
    assert_eq!(
        outside(30, 0, 8, 8),
        "tile 8x8 at (30, 0) does not lie inside the 37x23 image"
    );
    outside(0, 16, 8, 8);
    outside(37, 0, 1, 1);
    outside(0, 0, 38, 23);
    // `x + width` overflows a u32.
    outside(u32::MAX, 0, 2, 1);
    outside(1, 1, u32::MAX, 1);

    for (width, height) in [(0, 4), (4, 0), (0, 0)] {
        let tile = Tile {
            x: 2,
            y: 2,
            width,
            height,
        };
        let err = render_tile(&scene, &options, tile).unwrap_err();
        assert_eq!(err, TileError::Empty { tile });
        assert_eq!(
            err.to_string(),
            format!("tile {width}x{height} at (2, 2) has no pixels")
        );
    }
}
