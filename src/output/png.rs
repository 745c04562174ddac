//! 8-bit RGB PNG files of a post-processed [`Image`].

use std::io::{self, BufWriter, Write};
use std::path::Path;

use super::atomic::{WriteError, write_atomically};
use crate::postprocess::Image;

impl Image {
    /// Writes the image as an 8-bit RGB PNG, atomically: into a temporary file in the
    /// same folder, renamed over `path` only once complete. A failure leaves any
    /// existing file untouched and no temporary file behind; so does an interrupt, if
    /// its handler calls [`super::remove_temp_files`].
    ///
    /// # Errors
    /// As [`super::check_output`], or the disk is full.
    pub fn write_png(&self, path: &Path) -> Result<(), WriteError> {
        write_atomically(path, "png", |file| {
            let mut writer = BufWriter::new(file);
            let mut encoder = png::Encoder::new(&mut writer, self.width, self.height);
            encoder.set_color(png::ColorType::Rgb);
            // fdeflate: several times faster than zlib level 6 on renders, for files
            // a few percent larger.
            encoder.set_compression(png::Compression::Fast);
            encoder.set_depth(png::BitDepth::Eight);
            let mut png_writer = encoder.write_header().map_err(io::Error::other)?;
            png_writer
                .write_image_data(&self.rgb)
                .map_err(io::Error::other)?;
            png_writer.finish().map_err(io::Error::other)?;
            writer.flush()
        })
    }
}
