//! The OBJ reader: `v`, `vt`, `vn`, `f` (any polygon, all four vertex forms, negative
//! indices), `s` (smoothing groups), `mtllib`, `usemtl`, and the extensions `S` (sphere)
//! and `P` (point light). `l`, `p` and faces of fewer than 3 corners are skipped with
//! one warning per kind, vertex values such as `3.1+e2` read as their leading number
//! with one warning, and a missing `.mtl` with one warning.
//!
//! Large files are parsed in parallel, in three passes over chunks cut at line ends,
//! and a fourth over the faces:
//! 1. each chunk is surveyed ([`survey`]) on its own, as soon as it is read: its
//!    lines, elements and triangles are counted without reading a number, and the
//!    rare statements are read in full: `mtllib` and `usemtl`, whose meaning depends
//!    on earlier chunks, are recorded as events, and shapes refer to "the material
//!    of the chunk's k-th `usemtl`" (0: the one in force when the chunk starts);
//! 2. in file order, the MTL files are loaded and the events resolved to material
//!    ids; the counts give every chunk its place in the final arrays;
//! 3. each chunk's `v`, `vt`, `vn` and `f` lines are parsed straight into their
//!    place ([`scan`]), indices resolved against the elements before the chunk; on
//!    anything uncommon the general parser, which stops at the first problem, reads
//!    the chunk instead. Polygons are written as fans, and noted;
//! 4. once every position is known, polygons that are not convex are cut again by ear
//!    clipping, and faces of smoothing groups get their normals ([`faces`]).
//!
//! The first problem in file order is the one reported, exactly as a sequential
//! reader would.

use std::cell::Cell;
use std::collections::{HashMap, HashSet};
use std::mem::MaybeUninit;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

use rayon::prelude::*;

use super::error::{IndexKind, ParseErrorKind, SceneError};
use super::{
    FileAccess, SceneDescription, SphereDesc, TriangleDesc, file, finite, lex, mtl, read_file,
};
use crate::material::{Light, Material, MaterialId};
use crate::math::{Vec2, Vec3};
use crate::memory;
use faces::{ChunkFaces, INHERITED_GROUP, Shaping};
use scan::Parts;
use survey::Survey;

mod faces;
mod scan;
mod survey;

/// Target size of a chunk: big enough that per-chunk work is negligible, small
/// enough to spread a mesh file over all cores.
const CHUNK_BYTES: usize = 1 << 20;

/// Reads an OBJ file and the MTL files it names (relative to its folder).
///
/// Chunks are surveyed (pass 1) as soon as they are read, while the rest of the
/// file is read.
///
/// # Errors
/// A missing or unreadable file (naming its path), or a malformed supported line
/// (naming file and line).
pub fn load_obj(path: &Path) -> Result<SceneDescription, SceneError> {
    load_obj_with(path, &FileAccess::anywhere())
}

/// [`load_obj`], opening its MTL libraries and textures through `access`.
///
/// # Errors
/// As [`load_obj`]; a library `access` refuses is an error of the line naming it, a
/// texture it refuses a warning.
pub fn load_obj_with(path: &Path, access: &FileAccess) -> Result<SceneDescription, SceneError> {
    super::admit(path, access)?;
    if let Some(text) = file::map_uncompressed(path)? {
        return parse_in_chunks(&text, path, access, CHUNK_BYTES, Parser::Fast);
    }
    let mut buffer = Vec::new();
    let read = Mutex::new(Vec::new());
    let whole = rayon::in_place_scope_fifo(|scope| {
        file::read_in_pieces(path, CHUNK_BYTES, &mut buffer, |index, chunk| {
            let read = &read;
            scope.spawn_fifo(move |_| {
                let survey = survey::survey(chunk);
                let mut read = read.lock().unwrap_or_else(PoisonError::into_inner);
                read.push((index, chunk, survey));
            });
        })
    })?;
    if let Some(text) = whole {
        return parse_in_chunks(&text, path, access, CHUNK_BYTES, Parser::Fast);
    }
    let mut read = read.into_inner().unwrap_or_else(PoisonError::into_inner);
    read.sort_unstable_by_key(|&(index, ..)| index);
    let (chunks, surveys): (Vec<&[u8]>, Vec<Survey>) = read
        .into_iter()
        .map(|(_, text, survey)| (text, survey))
        .unzip();
    parse_surveyed(&chunks, surveys, path, access)
}

/// Parses OBJ text; `path` names it in messages and locates `mtllib` files.
///
/// # Errors
/// As [`load_obj`].
pub fn parse_obj(text: &[u8], path: &Path) -> Result<SceneDescription, SceneError> {
    parse_in_chunks(
        text,
        path,
        &FileAccess::anywhere(),
        CHUNK_BYTES,
        Parser::Fast,
    )
}

/// The readers of [`parse_in_chunks`]; tests compare them.
#[derive(Clone, Copy, PartialEq)]
enum Parser {
    /// Survey, resolve, then fill the final arrays.
    Fast,
    /// The general parser on every chunk.
    #[cfg(test)]
    General,
}

fn parse_in_chunks(
    text: &[u8],
    path: &Path,
    access: &FileAccess,
    chunk_bytes: usize,
    parser: Parser,
) -> Result<SceneDescription, SceneError> {
    let chunks = split_into_chunks(text, chunk_bytes);
    let mut scene = match parser {
        Parser::Fast => {
            let surveys = chunks.par_iter().map(|text| survey::survey(text)).collect();
            parse_surveyed(&chunks, surveys, path, access)
        }
        #[cfg(test)]
        Parser::General => parse_generally(&chunks, path, access),
    }?;
    finite::drop_non_finite_triangles(&mut scene, path);
    Ok(scene)
}

/// Refuses binary data, which would otherwise be read as lines of unknown
/// statements: the first NUL byte is an error of its line.
fn check_text(chunks: &[&[u8]], path: &Path) -> Result<(), SceneError> {
    let mut lines_before = 0;
    for text in chunks {
        if let Err((line, kind)) = lex::check_text(text) {
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                line: lines_before + line,
                kind,
            });
        }
        lines_before += memchr::memchr_iter(b'\n', text).count();
    }
    Ok(())
}

/// The counts of everything before each chunk, and of the whole file.
fn bases<'a>(counts: impl Iterator<Item = &'a Counts>) -> (Vec<Counts>, Counts) {
    let mut total = Counts::default();
    let bases = counts
        .map(|counts| {
            let base = total;
            total.add(counts);
            base
        })
        .collect();
    (bases, total)
}

/// Passes 2 and 3, after pass 1 surveyed the chunks of a file.
fn parse_surveyed(
    chunks: &[&[u8]],
    surveys: Vec<Survey>,
    path: &Path,
    access: &FileAccess,
) -> Result<SceneDescription, SceneError> {
    if surveys.iter().any(|survey| survey.has_nul) {
        check_text(chunks, path)?;
    }
    let (bases, total) = bases(surveys.iter().map(|survey| &survey.counts));
    let statements: Vec<Chunk> = surveys
        .into_iter()
        .zip(&bases)
        .map(|(survey, base)| survey.statements.placed_after(base))
        .collect();

    // Pass 2: the events in file order. A problem is only a candidate: a chunk's
    // elements and faces, not parsed yet, may hold an earlier one.
    let mut resolver = Resolver::new(path, access, &statements);
    let mut materials = Vec::with_capacity(chunks.len());
    for (chunk, statements) in statements.iter().enumerate() {
        match resolver.resolve(statements, total_triangles_to(&bases, &total, chunk)) {
            Ok(slots) => materials.push(slots),
            Err(stop) => return Err(first_problem(chunks, &bases, chunk, stop, path)),
        }
    }

    // Pass 3: every chunk into its parts of the final arrays.
    let mut scene = std::mem::take(&mut resolver.scene);
    let lengths = |count: fn(&Counts) -> usize| -> Vec<usize> {
        let mut lengths: Vec<usize> = bases.iter().skip(1).map(count).collect();
        lengths.push(count(&total));
        let mut before = 0;
        for length in &mut lengths {
            let end = *length;
            *length = end - before;
            before = end;
        }
        lengths
    };
    // Pass 1 counts the triangles of faces that may turn out malformed: memory
    // for them is asked for fallibly, so that a file claiming absurdly many gets
    // the general parser's error rather than an abort.
    let keep_texcoords = keeps_triangle_texcoords(&total, &scene);
    let keep_normals = keeps_triangle_normals(&total);
    let reserved = scene.positions.try_reserve_exact(total.positions).is_ok()
        && scene.texcoords.try_reserve_exact(total.texcoords).is_ok()
        && scene.normals.try_reserve_exact(total.normals).is_ok()
        && scene.triangles.try_reserve_exact(total.triangles).is_ok()
        && (!keep_texcoords
            || (scene.triangle_texcoords)
                .try_reserve_exact(total.triangles)
                .is_ok())
        && (!keep_normals
            || (scene.triangle_normals)
                .try_reserve_exact(total.triangles)
                .is_ok());
    if !reserved {
        return parse_generally(chunks, path, access);
    }
    let positions = parts_of(&mut scene.positions, lengths(|c| c.positions));
    let texcoords = parts_of(&mut scene.texcoords, lengths(|c| c.texcoords));
    let normals = parts_of(&mut scene.normals, lengths(|c| c.normals));
    let triangles = parts_of(&mut scene.triangles, lengths(|c| c.triangles));
    let triangle_texcoords = kept_parts_of(
        &mut scene.triangle_texcoords,
        keep_texcoords,
        lengths(|c| c.triangles),
    );
    let triangle_normals = kept_parts_of(
        &mut scene.triangle_normals,
        keep_normals,
        lengths(|c| c.triangles),
    );
    let parts: Vec<Parts<'_>> = positions
        .into_iter()
        .zip(texcoords)
        .zip(normals)
        .zip(triangles)
        .zip(triangle_texcoords)
        .zip(triangle_normals)
        .map(
            |(
                ((((positions, texcoords), normals), triangles), triangle_texcoords),
                triangle_normals,
            )| Parts {
                positions,
                texcoords,
                normals,
                triangles,
                triangle_texcoords,
                triangle_normals,
            },
        )
        .collect();
    let filled: Vec<Filled> = parts
        .into_par_iter()
        .zip(chunks)
        .zip(&bases)
        .zip(&materials)
        .map(|(((mut parts, text), base), materials)| fill(text, base, materials, &mut parts))
        .collect();
    let mut complete = true;
    let mut shapings = Vec::with_capacity(filled.len());
    let mut colours = Vec::with_capacity(filled.len());
    for filled in filled {
        match filled {
            Filled::Complete(shaping, chunk_colours, lenient) => {
                shapings.push(shaping);
                colours.push(chunk_colours);
                resolver.skipped[Skipped::LENIENT_NUMBER].add(&lenient);
            }
            Filled::Failed { line, kind } => {
                return Err(SceneError::Parse {
                    path: path.to_path_buf(),
                    line,
                    kind,
                });
            }
            Filled::Incomplete => complete = false,
        }
    }
    if !complete {
        // The counts of pass 1 and the elements of pass 3 disagree, which they
        // cannot for a chunk without errors; should they ever, read the file as
        // the general parser does, rather than leave an element unwritten.
        return parse_generally(chunks, path, access);
    }
    // SAFETY: the parts split the first `total` elements of each array's spare
    // capacity (see `parts_of`), and every chunk's fill was `Complete`: it wrote
    // every element of every one of its parts. (Writing into uninitialised memory
    // rather than first filling the arrays with placeholders saves a pass over
    // them: 5 ms of CPU of the 871k-triangle dragon's 80.)
    unsafe {
        scene.positions.set_len(total.positions);
        scene.texcoords.set_len(total.texcoords);
        scene.normals.set_len(total.normals);
        scene.triangles.set_len(total.triangles);
        if keep_texcoords {
            scene.triangle_texcoords.set_len(total.triangles);
        }
        if keep_normals {
            scene.triangle_normals.set_len(total.triangles);
        }
    }
    spread_colours(
        &mut scene,
        (bases.iter().map(|b| b.positions)).zip(colours.iter().map(Vec::as_slice)),
    );
    let material = |chunk: usize, slot: MaterialId| materials[chunk][slot.0 as usize];
    let sphere = |chunk, s: &SphereDesc| SphereDesc {
        material: material(chunk, s.material),
        ..*s
    };
    concat(&statements, |c| &c.spheres, sphere, &mut scene.spheres);
    concat(&statements, |c| &c.lights, |_, &l| l, &mut scene.lights);
    let chunk_faces = chunk_faces(&statements, &bases, shapings);
    faces::finish(&mut scene, chunk_faces);
    resolver.finish_warnings(&mut scene);
    Ok(scene)
}

/// Each chunk's notes for pass 4, placed: where its triangles start, and the smoothing
/// group in force at its start (the last `s` of the chunks before it, 0 if none).
fn chunk_faces(statements: &[Chunk], bases: &[Counts], shapings: Vec<Shaping>) -> Vec<ChunkFaces> {
    let mut group = 0;
    statements
        .iter()
        .zip(bases)
        .zip(shapings)
        .map(|((chunk, base), shaping)| {
            let faces = ChunkFaces {
                shaping,
                first_triangle: base.triangles,
                group_before: group,
            };
            group = chunk.smoothing.unwrap_or(group);
            faces
        })
        .collect()
}

/// Whether the description keeps each triangle's texture coordinate indices: only
/// when the file has texture coordinates and a material (all loaded by now) has a map
/// to read with them. Most large meshes have neither, and pay nothing.
fn keeps_triangle_texcoords(total: &Counts, scene: &SceneDescription) -> bool {
    total.texcoords > 0 && scene.materials.iter().any(Material::needs_texcoords)
}

/// Whether the description keeps each triangle's normal indices as read: only when
/// the file has normals (smoothing groups may add some later, see `faces::finish`).
/// Scans, the largest meshes, mostly have none, and pay nothing.
fn keeps_triangle_normals(total: &Counts) -> bool {
    total.normals > 0
}

/// The triangles of the chunks up to and including `chunk`.
fn total_triangles_to(bases: &[Counts], total: &Counts, chunk: usize) -> usize {
    bases.get(chunk + 1).unwrap_or(total).triangles
}

/// `out`'s spare capacity, reserved for the sum of `lengths`, cut into parts of
/// those lengths.
fn parts_of<T>(out: &mut Vec<T>, lengths: Vec<usize>) -> Vec<&mut [MaybeUninit<T>]> {
    let total = lengths.iter().sum();
    out.clear();
    out.reserve_exact(total);
    // Written once, in parallel, straight after: the mesh's big arrays (the dragon's
    // triangles take 28 MB) fault in a fraction of the time on huge pages.
    memory::advise_huge_pages(out);
    let mut rest = &mut out.spare_capacity_mut()[..total];
    lengths
        .into_iter()
        .map(|length| {
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(length);
            rest = tail;
            part
        })
        .collect()
}

/// [`parts_of`] for an array the description keeps only when `keep`; otherwise no
/// part for any chunk.
fn kept_parts_of<T>(
    out: &mut Vec<T>,
    keep: bool,
    lengths: Vec<usize>,
) -> Vec<Option<&mut [MaybeUninit<T>]>> {
    if keep {
        parts_of(out, lengths).into_iter().map(Some).collect()
    } else {
        lengths.iter().map(|_| None).collect()
    }
}

/// What pass 3 made of a chunk.
enum Filled {
    /// Every element of the chunk's parts is written; what pass 4 needs of its
    /// faces, its vertex colours ([`Chunk::colours`]), and its vertex lines read
    /// leniently (which only the general parser reads, so pass 1 cannot count them).
    Complete(Shaping, Vec<(u32, Vec3)>, Skipped),
    /// The chunk's first problem, at `line` of the file.
    Failed { line: usize, kind: ParseErrorKind },
    /// The chunk has more or fewer elements than pass 1 counted.
    Incomplete,
}

/// Pass 3 on one chunk: the scanner, or the general parser if it gives up.
fn fill(text: &[u8], base: &Counts, materials: &[MaterialId], parts: &mut Parts<'_>) -> Filled {
    let mut shaping = Shaping::default();
    if scan::fill(text, base, materials, parts, &mut shaping).is_some() {
        return Filled::Complete(shaping, Vec::new(), Skipped::default());
    }
    let mut chunk = Chunk::parse(text, *base);
    if let Some((line, kind)) = chunk.error {
        return Filled::Failed { line, kind };
    }
    let triangles: Option<Vec<TriangleDesc>> = (chunk.triangles.iter())
        .map(|t| {
            Some(TriangleDesc {
                material: *materials.get(t.material.0 as usize)?,
                ..*t
            })
        })
        .collect();
    let triangle_texcoords = match &mut parts.triangle_texcoords {
        Some(part) => copy_into(&chunk.triangle_texcoords, part),
        None => true,
    };
    let triangle_normals = match &mut parts.triangle_normals {
        Some(part) => copy_into(&chunk.triangle_normals, part),
        None => true,
    };
    match triangles {
        Some(triangles)
            if copy_into(&chunk.positions, parts.positions)
                && copy_into(&chunk.texcoords, parts.texcoords)
                && copy_into(&chunk.normals, parts.normals)
                && copy_into(&triangles, parts.triangles)
                && triangle_texcoords
                && triangle_normals =>
        {
            Filled::Complete(
                std::mem::take(&mut chunk.shaping),
                std::mem::take(&mut chunk.colours),
                chunk.skipped[Skipped::LENIENT_NUMBER],
            )
        }
        _ => Filled::Incomplete,
    }
}

/// The colour of a `v` line whose position is followed by exactly three numbers
/// (`v x y z r g b`, 0 to 1; a fourth value alone is `w`, ignored as before, and so
/// is anything else, or a colour that is not finite); negative channels read as 0.
fn vertex_colour(mut tokens: lex::Tokens<'_>) -> Option<Vec3> {
    let mut rgb = [0.0; 3];
    for channel in &mut rgb {
        *channel = lex::float(tokens.next()?).ok()?;
    }
    let colour = Vec3::from(rgb);
    (tokens.next().is_none() && colour.is_finite()).then(|| colour.max(Vec3::ZERO))
}

/// Spreads each chunk's vertex colours over `scene.colours` (white where a vertex
/// has none); `first` gives each chunk's first position. Leaves it empty when no
/// vertex has a colour.
fn spread_colours<'a>(
    scene: &mut SceneDescription,
    chunks: impl Iterator<Item = (usize, &'a [(u32, Vec3)])> + Clone,
) {
    if chunks.clone().all(|(_, colours)| colours.is_empty()) {
        return;
    }
    scene.colours = vec![Vec3::ONE; scene.positions.len()];
    for (first, colours) in chunks {
        for &(index, colour) in colours {
            if let Some(slot) = scene.colours.get_mut(first + index as usize) {
                *slot = colour;
            }
        }
    }
}

/// Writes `from` into `to` if they are as long.
fn copy_into<T: Copy>(from: &[T], to: &mut [MaybeUninit<T>]) -> bool {
    if from.len() != to.len() {
        return false;
    }
    for (slot, &value) in to.iter_mut().zip(from) {
        slot.write(value);
    }
    true
}

/// Where pass 2 stopped, at a chunk: the first problem the resolver sees there.
enum Stop {
    /// Reading the MTL file named at `line` failed.
    Event { line: usize, error: SceneError },
    /// A statement that pass 1 read is malformed.
    Problem(SceneError),
    /// The triangles up to the chunk are too many.
    TooMany(SceneError),
}

/// The problem to report when pass 2 stopped at `chunk`: the first of the chunks
/// before it, if any has one; else the first in file order in that chunk, as a
/// sequential reader meets them.
fn first_problem(
    chunks: &[&[u8]],
    bases: &[Counts],
    chunk: usize,
    stop: Stop,
    path: &Path,
) -> SceneError {
    let parse_error = |(line, kind)| SceneError::Parse {
        path: path.to_path_buf(),
        line,
        kind,
    };
    let mut errors: Vec<Option<(usize, ParseErrorKind)>> = (0..=chunk)
        .into_par_iter()
        .map(|i| Chunk::parse(chunks[i], bases[i]).error)
        .collect();
    let own = errors.pop().flatten();
    if let Some(earlier) = errors.into_iter().flatten().next() {
        return parse_error(earlier);
    }
    match (own, stop) {
        // The general parser stops at a chunk's first problem: events after it
        // were never read.
        (Some(own), Stop::Event { line, .. }) if own.0 < line => parse_error(own),
        (_, Stop::Event { error, .. }) => error,
        (Some(own), _) => parse_error(own),
        (None, Stop::Problem(error) | Stop::TooMany(error)) => error,
    }
}

/// Passes 1 to 3 with the general parser on every chunk: the reference the
/// scanner is tested against, and the way out should the counts of pass 1 ever
/// disagree with the elements.
fn parse_generally(
    chunks: &[&[u8]],
    path: &Path,
    access: &FileAccess,
) -> Result<SceneDescription, SceneError> {
    check_text(chunks, path)?;
    let counts: Vec<Counts> = chunks.par_iter().map(|text| Counts::of(text)).collect();
    let (bases, _) = bases(counts.iter());
    let mut parsed: Vec<Chunk> = chunks
        .par_iter()
        .zip(bases)
        .map(|(text, base)| Chunk::parse(text, base))
        .collect();
    let mut resolver = Resolver::new(path, access, &parsed);
    let mut materials = Vec::with_capacity(parsed.len());
    let mut triangles = 0;
    let mut bases = Vec::with_capacity(parsed.len());
    for chunk in &parsed {
        bases.push(Counts {
            triangles,
            ..Counts::default()
        });
        triangles += chunk.triangles.len();
        match resolver.resolve(chunk, triangles) {
            Ok(slots) => materials.push(slots),
            Err(Stop::Event { error, .. } | Stop::Problem(error) | Stop::TooMany(error)) => {
                return Err(error);
            }
        }
    }
    let mut scene = std::mem::take(&mut resolver.scene);
    let total = Counts {
        texcoords: parsed.iter().map(|c| c.texcoords.len()).sum(),
        normals: parsed.iter().map(|c| c.normals.len()).sum(),
        ..Counts::default()
    };
    if keeps_triangle_texcoords(&total, &scene) {
        concat(
            &parsed,
            |c| &c.triangle_texcoords,
            |_, &t| t,
            &mut scene.triangle_texcoords,
        );
    }
    if keeps_triangle_normals(&total) {
        concat(
            &parsed,
            |c| &c.triangle_normals,
            |_, &n| n,
            &mut scene.triangle_normals,
        );
    }
    concat(&parsed, |c| &c.positions, |_, &p| p, &mut scene.positions);
    let firsts = parsed.iter().scan(0, |first, c| {
        let at = *first;
        *first += c.positions.len();
        Some(at)
    });
    spread_colours(
        &mut scene,
        firsts.zip(parsed.iter().map(|c| c.colours.as_slice())),
    );
    concat(&parsed, |c| &c.texcoords, |_, &t| t, &mut scene.texcoords);
    concat(&parsed, |c| &c.normals, |_, &n| n, &mut scene.normals);
    let material = |chunk: usize, slot: MaterialId| materials[chunk][slot.0 as usize];
    let triangle = |chunk, t: &TriangleDesc| TriangleDesc {
        material: material(chunk, t.material),
        ..*t
    };
    concat(&parsed, |c| &c.triangles, triangle, &mut scene.triangles);
    let sphere = |chunk, s: &SphereDesc| SphereDesc {
        material: material(chunk, s.material),
        ..*s
    };
    concat(&parsed, |c| &c.spheres, sphere, &mut scene.spheres);
    concat(&parsed, |c| &c.lights, |_, &l| l, &mut scene.lights);
    let shapings = parsed
        .iter_mut()
        .map(|c| std::mem::take(&mut c.shaping))
        .collect();
    let chunk_faces = chunk_faces(&parsed, &bases, shapings);
    faces::finish(&mut scene, chunk_faces);
    resolver.finish_warnings(&mut scene);
    Ok(scene)
}

/// Fills `out` with every chunk's `part`, in file order, each element passed through
/// `map` with its chunk's index. Each chunk's elements are written by one thread,
/// all chunks at once, straight into `out`'s fresh memory.
fn concat<'c, T: Sync + 'c, U: Send>(
    chunks: &'c [Chunk],
    part: impl Fn(&'c Chunk) -> &'c [T],
    map: impl Fn(usize, &T) -> U + Sync,
    out: &mut Vec<U>,
) {
    let parts: Vec<&[T]> = chunks.iter().map(part).collect();
    let total = parts.iter().map(|p| p.len()).sum();
    out.clear();
    out.reserve_exact(total);
    // One disjoint piece of the spare capacity per part, as long as the part.
    let mut rest = &mut out.spare_capacity_mut()[..total];
    let mut pieces = Vec::with_capacity(parts.len());
    for part in &parts {
        let (piece, tail) = rest.split_at_mut(part.len());
        pieces.push(piece);
        rest = tail;
    }
    pieces
        .into_par_iter()
        .zip(parts)
        .enumerate()
        .for_each(|(i, (piece, part))| {
            for (slot, element) in piece.iter_mut().zip(part) {
                slot.write(map(i, element));
            }
        });
    // SAFETY: the pieces cover the first `total` elements of the spare capacity,
    // and every element of every piece was written above: a piece is exactly as
    // long as the part it was zipped with. (Writing into uninitialised memory
    // rather than first filling `out` with placeholders saves a pass over the
    // largest arrays: concatenating the 871k-triangle dragon took 16 ms of CPU with
    // a parallel fill first, 11 ms without.) Had a thread panicked, this line would
    // not run and `out` would stay empty.
    unsafe { out.set_len(total) };
}

/// Cuts `text` into pieces of about `size` bytes, each ending just after a `\n`
/// (the last one at the end of the text).
fn split_into_chunks(text: &[u8], size: usize) -> Vec<&[u8]> {
    let mut chunks = Vec::with_capacity(text.len() / size + 1);
    let mut rest = text;
    while rest.len() > size {
        let Some(newline) = memchr::memchr(b'\n', &rest[size..]) else {
            break;
        };
        let (chunk, tail) = rest.split_at(size + newline + 1);
        chunks.push(chunk);
        rest = tail;
    }
    chunks.push(rest);
    chunks
}

/// How many lines and elements a piece of the file holds.
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    lines: usize,
    positions: usize,
    texcoords: usize,
    normals: usize,
    /// Counted by pass 1 only.
    triangles: usize,
}

impl Counts {
    /// Counts without parsing: a line counts as a `v`, `vt` or `vn` statement by its
    /// keyword alone, exactly as [`Chunk::parse`] dispatches it.
    fn of(text: &[u8]) -> Counts {
        let mut counts = Counts {
            lines: memchr::memchr_iter(b'\n', text).count(),
            ..Counts::default()
        };
        for (_, line) in lex::lines(text) {
            let Some(start) = line.iter().position(|&b| !lex::is_space(b)) else {
                continue;
            };
            let line = &line[start..];
            let ends_keyword = |at: usize| line.get(at).is_none_or(|&b| lex::is_space(b));
            match line {
                [b'v', ..] if ends_keyword(1) => counts.positions += 1,
                [b'v', b't', ..] if ends_keyword(2) => counts.texcoords += 1,
                [b'v', b'n', ..] if ends_keyword(2) => counts.normals += 1,
                _ => {}
            }
        }
        counts
    }

    fn add(&mut self, other: &Counts) {
        self.lines += other.lines;
        self.positions += other.positions;
        self.texcoords += other.texcoords;
        self.normals += other.normals;
        self.triangles += other.triangles;
    }
}

/// Statements that other tools write and this renderer skips, or reads leniently, with
/// one warning per kind (as Blender's importer and tinyobjloader read such files): the
/// first line of each kind and how many there were.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Skipped {
    first_line: usize,
    count: usize,
}

impl Skipped {
    /// `l` (polylines), `p` (points), faces of fewer than 3 corners, and vertex
    /// lines with a number followed by other characters (read by its leading
    /// number, not skipped).
    const KINDS: usize = 4;
    const LINE: usize = 0;
    const POINT: usize = 1;
    const SHORT_FACE: usize = 2;
    const LENIENT_NUMBER: usize = 3;

    fn note(&mut self, line: usize) {
        if self.count == 0 {
            self.first_line = line;
        }
        self.count += 1;
    }

    /// `other`, which comes later in the file, added.
    fn add(&mut self, other: &Skipped) {
        if self.count == 0 {
            self.first_line = other.first_line;
        }
        self.count += other.count;
    }

    fn warning(kind: usize, count: usize) -> String {
        let s = if count == 1 { "" } else { "s" };
        match kind {
            Skipped::LINE => {
                format!("skipped {count} line element{s} ('l'): lines have no area to render")
            }
            Skipped::POINT => {
                format!("skipped {count} point element{s} ('p'): points have no area to render")
            }
            Skipped::SHORT_FACE => format!("skipped {count} face{s} of fewer than 3 vertices"),
            _ => format!(
                "read {count} vertex line{s} with a number followed by other characters \
                 (such as '3.1+e2') by the leading number (3.1), as assimp, tinyobjloader \
                 and Blender do"
            ),
        }
    }
}

/// A statement whose effect depends on earlier chunks, replayed in file order.
enum Event {
    /// `names`: the line's names split at spaces; `whole`: the rest of the line as
    /// one name, tried first when there are several (`mtllib Part Studio 1.mtl`).
    Mtllib {
        line: usize,
        names: Vec<PathBuf>,
        whole: PathBuf,
    },
    Usemtl {
        line: usize,
        name: String,
    },
}

/// One chunk's elements. Shape materials are slots: 0 is the material in force when
/// the chunk starts, `k` the one set by the chunk's `k`-th `usemtl`.
#[derive(Default)]
struct Chunk {
    positions: Vec<Vec3>,
    texcoords: Vec<Vec2>,
    normals: Vec<Vec3>,
    triangles: Vec<TriangleDesc>,
    /// Texture coordinate indices of each triangle, in step with `triangles`.
    triangle_texcoords: Vec<Option<[u32; 3]>>,
    /// Normal indices of each triangle, in step with `triangles`.
    triangle_normals: Vec<Option<[u32; 3]>>,
    /// The colours of `v x y z r g b` lines (Blender's and MeshLab's extension), by
    /// index among the chunk's positions: few files have them, so they are kept
    /// apart and spread over [`SceneDescription::colours`] once the file is read.
    colours: Vec<(u32, Vec3)>,
    spheres: Vec<SphereDesc>,
    lights: Vec<Light>,
    events: Vec<Event>,
    /// Line of the first shape using slot 0, for the "no usemtl" warning.
    first_inherited_shape: Option<usize>,
    /// Statements skipped with a warning, by [`Skipped`] kind.
    skipped: [Skipped; Skipped::KINDS],
    /// The smoothing group of the chunk's last `s` statement (0 for `s off`), if any.
    smoothing: Option<u32>,
    /// What pass 4 needs of the faces (the general parser's; the scanner notes its own).
    shaping: Shaping,
    /// The first malformed line; parsing stopped there.
    error: Option<(usize, ParseErrorKind)>,
    /// Number of the chunk's first line.
    first_line: usize,
}

/// One corner of a face, resolved to 0-based indices.
#[derive(Clone, Copy)]
struct Corner {
    position: u32,
    texcoord: Option<u32>,
    normal: Option<u32>,
}

impl Chunk {
    /// Pass 1's statements of a chunk with their line numbers made global, once
    /// `base` is known.
    fn placed_after(mut self, base: &Counts) -> Chunk {
        self.first_line = base.lines + 1;
        for event in &mut self.events {
            match event {
                Event::Mtllib { line, .. } | Event::Usemtl { line, .. } => *line += base.lines,
            }
        }
        if let Some(line) = &mut self.first_inherited_shape {
            *line += base.lines;
        }
        for skipped in &mut self.skipped {
            if skipped.count > 0 {
                skipped.first_line += base.lines;
            }
        }
        if let Some((line, _)) = &mut self.error {
            *line += base.lines;
        }
        self
    }

    /// The general parser: resolves indices against `base`, the counts of everything
    /// before the chunk, and stops at the first problem.
    fn parse(text: &[u8], base: Counts) -> Chunk {
        let mut chunk = Chunk {
            first_line: base.lines + 1,
            ..Chunk::default()
        };
        let mut slot = 0u32;
        for (local_line, line) in lex::lines(text) {
            let line_number = base.lines + local_line;
            if let Err(kind) = chunk.parse_line(line, line_number, &base, &mut slot) {
                chunk.error = Some((line_number, kind));
                break;
            }
        }
        chunk
    }

    fn parse_line(
        &mut self,
        line: &[u8],
        line_number: usize,
        base: &Counts,
        slot: &mut u32,
    ) -> Result<(), ParseErrorKind> {
        let mut tokens = lex::tokens(line);
        let Some(keyword) = tokens.next() else {
            return Ok(());
        };
        if keyword == b"f" {
            return self.parse_face(tokens, line_number, base, *slot);
        }
        self.parse_statement(keyword, tokens, line, line_number, slot)
    }

    /// Any statement but `f`: none depends on the elements before it.
    fn parse_statement(
        &mut self,
        keyword: &[u8],
        mut tokens: lex::Tokens<'_>,
        line: &[u8],
        line_number: usize,
        slot: &mut u32,
    ) -> Result<(), ParseErrorKind> {
        let lenient = Cell::new(false);
        let leading = |token: &[u8]| lex::leading_float(token, &lenient);
        match keyword {
            b"v" => {
                let position = Vec3::from(lex::numbers::<3>("v", &mut tokens, leading)?);
                if let Some(colour) = vertex_colour(tokens) {
                    self.colours.push((self.positions.len() as u32, colour));
                }
                self.positions.push(position);
            }
            // Non-finite normals and texture coordinates, like positions, are read
            // and left out of the triangles using them once the file is read.
            b"vn" => {
                let normal = lex::numbers::<3>("vn", &mut tokens, leading)?;
                self.normals.push(Vec3::from(normal));
            }
            b"vt" => {
                let u = lex::numbers::<1>("vt", &mut tokens, leading)?[0];
                let v = match tokens.next() {
                    Some(t) => leading(t)?,
                    None => 0.0,
                };
                self.texcoords.push(Vec2::new(u, v));
            }
            b"S" => {
                let [x, y, z, radius] = lex::floats::<4>("S", &mut tokens)?;
                if radius < 0.0 {
                    return Err(ParseErrorKind::NegativeRadius(radius));
                }
                self.note_shape(line_number, *slot);
                self.spheres.push(SphereDesc {
                    center: Vec3::new(x, y, z),
                    radius,
                    material: MaterialId(*slot),
                });
            }
            b"l" => self.skipped[Skipped::LINE].note(line_number),
            b"p" => self.skipped[Skipped::POINT].note(line_number),
            b"s" => self.smoothing = Some(smoothing_group(tokens.next())?),
            b"P" => {
                let [x, y, z, r, g, b] = lex::floats::<6>("P", &mut tokens)?;
                self.lights
                    .push(Light::point(Vec3::new(x, y, z), Vec3::new(r, g, b)));
            }
            b"mtllib" => {
                let path = |name: &[u8]| PathBuf::from(String::from_utf8_lossy(name).as_ref());
                let names: Vec<PathBuf> = tokens.map(path).collect();
                if names.is_empty() {
                    return Err(ParseErrorKind::MissingName("mtllib"));
                }
                self.events.push(Event::Mtllib {
                    line: line_number,
                    names,
                    whole: path(lex::rest_of_line(line, b"mtllib")),
                });
            }
            b"usemtl" => {
                // An empty name is a name: Blender writes `newmtl` and `usemtl` with
                // none.
                let name = lex::rest_of_line(line, b"usemtl");
                self.events.push(Event::Usemtl {
                    line: line_number,
                    name: String::from_utf8_lossy(name).into_owned(),
                });
                *slot += 1;
            }
            _ => {}
        }
        if lenient.get() {
            self.skipped[Skipped::LENIENT_NUMBER].note(line_number);
        }
        Ok(())
    }

    /// Notes a face of `corners` corners that pass 1 counted: a shape, or skipped.
    fn note_face(&mut self, corners: usize, line_number: usize, slot: u32) {
        if corners < 3 {
            self.skipped[Skipped::SHORT_FACE].note(line_number);
        } else {
            self.note_shape(line_number, slot);
        }
    }

    fn note_shape(&mut self, line_number: usize, slot: u32) {
        if slot == 0 && self.first_inherited_shape.is_none() {
            self.first_inherited_shape = Some(line_number);
        }
    }

    fn parse_face(
        &mut self,
        tokens: lex::Tokens<'_>,
        line_number: usize,
        base: &Counts,
        slot: u32,
    ) -> Result<(), ParseErrorKind> {
        let mut first: Option<Corner> = None;
        let mut previous: Option<Corner> = None;
        let mut count = 0usize;
        let mut all_normals = true;
        let start = self.triangles.len();
        for token in tokens {
            let corner = self.parse_corner(token, base)?;
            count += 1;
            all_normals &= corner.normal.is_some();
            if let (Some(a), Some(b), 3..) = (first, previous, count) {
                let normals = match (a.normal, b.normal, corner.normal) {
                    (Some(na), Some(nb), Some(nc)) => Some([na, nb, nc]),
                    _ => None,
                };
                let texcoords = match (a.texcoord, b.texcoord, corner.texcoord) {
                    (Some(ta), Some(tb), Some(tc)) => Some([ta, tb, tc]),
                    _ => None,
                };
                self.triangles.push(TriangleDesc {
                    positions: [a.position, b.position, corner.position],
                    material: MaterialId(slot),
                });
                self.triangle_texcoords.push(texcoords);
                self.triangle_normals.push(normals);
            }
            first.get_or_insert(corner);
            previous = Some(corner);
        }
        if count < 3 {
            // Its corners were checked, as those of any face.
            self.skipped[Skipped::SHORT_FACE].note(line_number);
            return Ok(());
        }
        let group = self.smoothing.unwrap_or(INHERITED_GROUP);
        self.shaping
            .face(start, self.triangles.len() - start, all_normals, group);
        self.note_shape(line_number, slot);
        Ok(())
    }

    /// Parses `v`, `v/vt`, `v//vn` or `v/vt/vn` against the elements defined so far.
    fn parse_corner(&self, token: &[u8], base: &Counts) -> Result<Corner, ParseErrorKind> {
        let bad = || ParseErrorKind::BadFaceVertex(lex::show(token));
        let mut parts = token.split(|&b| b == b'/');
        let position = parts.next().filter(|p| !p.is_empty()).ok_or_else(bad)?;
        let texcoord = parts.next();
        let normal = parts.next();
        // `v/` and `v/vt/` are incomplete; only `v//vn` may leave the middle empty.
        let incomplete = texcoord.is_some_and(<[u8]>::is_empty) && normal.is_none();
        if parts.next().is_some() || incomplete || normal.is_some_and(<[u8]>::is_empty) {
            return Err(bad());
        }
        let texcoord = texcoord.filter(|t| !t.is_empty());
        let defined = |global: usize, local: usize| global + local;
        let position = resolve(
            position,
            IndexKind::Vertex,
            defined(base.positions, self.positions.len()),
        )?;
        let texcoord = texcoord
            .map(|vt| {
                let count = defined(base.texcoords, self.texcoords.len());
                resolve(vt, IndexKind::TexCoord, count)
            })
            .transpose()?;
        let normal = normal
            .map(|vn| {
                let count = defined(base.normals, self.normals.len());
                resolve(vn, IndexKind::Normal, count)
            })
            .transpose()?;
        Ok(Corner {
            position,
            texcoord,
            normal,
        })
    }
}

/// Pass 3: replays chunks' statements in file order.
struct Resolver<'a> {
    path: &'a Path,
    /// Where `mtllib` files and their textures may be read from.
    access: &'a FileAccess,
    scene: SceneDescription,
    material_ids: HashMap<String, MaterialId>,
    current_material: Option<MaterialId>,
    fallback_material: Option<MaterialId>,
    /// Whether the file has any `mtllib` or `usemtl`: only then are shapes before
    /// the first `usemtl` worth a warning (a file with neither, such as most scans
    /// and robot meshes, means the default material).
    names_materials: bool,
    warned_no_usemtl: bool,
    warned_unknown: HashSet<String>,
    /// Canonical paths of the `mtllib` files read so far.
    loaded_libraries: HashSet<PathBuf>,
    /// Whether an `mtllib` file was missing: then its names are unknown, and are not
    /// warned of one by one.
    missing_library: bool,
    /// Statements skipped so far, by [`Skipped`] kind.
    skipped: [Skipped; Skipped::KINDS],
}

impl<'a> Resolver<'a> {
    fn new(path: &'a Path, access: &'a FileAccess, chunks: &[Chunk]) -> Resolver<'a> {
        Resolver {
            names_materials: chunks.iter().any(|chunk| !chunk.events.is_empty()),
            path,
            access,
            scene: SceneDescription::default(),
            material_ids: HashMap::new(),
            current_material: None,
            fallback_material: None,
            warned_no_usemtl: false,
            warned_unknown: HashSet::new(),
            loaded_libraries: HashSet::new(),
            missing_library: false,
            skipped: [Skipped::default(); Skipped::KINDS],
        }
    }

    /// The warnings that sum up the whole file: one per kind of skipped statement.
    fn finish_warnings(&self, scene: &mut SceneDescription) {
        for (kind, skipped) in self.skipped.iter().enumerate() {
            if skipped.count > 0 {
                scene.warnings.push(format!(
                    "{}:{}: {}",
                    self.path.display(),
                    skipped.first_line,
                    Skipped::warning(kind, skipped.count)
                ));
            }
        }
    }

    /// Replays the chunk's statements that depend on earlier ones (reading MTL files,
    /// warning) and returns the material of each of its slots; the chunk's elements
    /// are appended afterwards, for all chunks at once.
    ///
    /// `triangles` counts the triangles of all chunks up to this one.
    fn resolve(&mut self, chunk: &Chunk, triangles: usize) -> Result<Vec<MaterialId>, Stop> {
        // Events all precede the chunk's error line (parsing stopped there), so
        // replaying them first reports problems in file order.
        let mut slots = vec![self.current_material];
        for event in &chunk.events {
            match event {
                Event::Mtllib { line, names, whole } => self
                    .load_mtllib(*line, names, whole)
                    .map_err(|error| Stop::Event { line: *line, error })?,
                Event::Usemtl { line, name } => {
                    let id = match self.material_ids.get(name) {
                        Some(&id) => id,
                        None => {
                            if self.warned_unknown.insert(name.clone()) && !self.missing_library {
                                // Shown cut, as tokens in errors are.
                                let shown = lex::show(name.as_bytes());
                                self.warn(
                                    *line,
                                    &format!(
                                        "unknown material '{shown}'; using the default material"
                                    ),
                                );
                            }
                            self.fallback_material()
                        }
                    };
                    self.current_material = Some(id);
                    slots.push(Some(id));
                }
            }
        }
        for (total, chunk) in self.skipped.iter_mut().zip(&chunk.skipped) {
            total.add(chunk);
        }
        if let Some((line, kind)) = &chunk.error {
            return Err(Stop::Problem(SceneError::Parse {
                path: self.path.to_path_buf(),
                line: *line,
                kind: kind.clone(),
            }));
        }
        if slots[0].is_none()
            && let Some(line) = chunk.first_inherited_shape
        {
            if self.names_materials && !self.warned_no_usemtl {
                self.warned_no_usemtl = true;
                self.warn(line, "shapes before any 'usemtl' get the default material");
            }
            slots[0] = Some(self.fallback_material());
        }
        if triangles > u32::MAX as usize {
            return Err(Stop::TooMany(SceneError::Parse {
                path: self.path.to_path_buf(),
                line: chunk.first_line,
                kind: ParseErrorKind::TooMany("triangles"),
            }));
        }
        Ok(slots.into_iter().map(Option::unwrap_or_default).collect())
    }

    /// `path` relative to the OBJ file's folder.
    fn beside(&self, relative: &Path) -> PathBuf {
        match self.path.parent() {
            Some(dir) => dir.join(relative),
            None => relative.to_path_buf(),
        }
    }

    /// Reads the libraries of an `mtllib` line. The OBJ format separates names by
    /// spaces, but exporters write one name with spaces in it (Onshape's `mtllib
    /// Part Studio 1.mtl`), which Assimp and Blender read as one file: a line of
    /// several names whose whole rest is a file reads that file alone. Otherwise
    /// each name is read; when none of them is found, one warning names the line's
    /// rest, not one per word.
    fn load_mtllib(
        &mut self,
        line: usize,
        names: &[PathBuf],
        whole: &Path,
    ) -> Result<(), SceneError> {
        if let [name] = names {
            return self.load_mtl(line, name, true).map(drop);
        }
        // Looked for first, then asked for: a render's list of the files it reads
        // (the Dask renderer's `scene_files`) holds no name that is not a file.
        let whole_path = self.beside(whole);
        if whole_path.is_file() && self.access.admit(&whole_path).is_ok() {
            return self.load_mtl(line, whole, true).map(drop);
        }
        let mut missing = Vec::new();
        for name in names {
            if !self.load_mtl(line, name, false)? {
                missing.push(name);
            }
        }
        let missing = if missing.len() == names.len() {
            vec![whole]
        } else {
            missing.into_iter().map(PathBuf::as_path).collect()
        };
        for name in missing {
            self.warn_missing_library(line, &self.beside(name));
        }
        Ok(())
    }

    fn warn_missing_library(&mut self, line: usize, path: &Path) {
        let shown = super::error::shown_path(path);
        self.warn(
            line,
            &format!("material library {shown} not found; its materials get the default material"),
        );
    }

    /// Reads the library `relative` named at line `line`, and says whether it was
    /// found; a missing one is warned about when `warn` says so. A library named again
    /// (under any spelling of its path) is not read again, so `mtllib a.mtl a.mtl ...`
    /// cannot multiply memory use; one that cannot be read is an error of that line.
    fn load_mtl(&mut self, line: usize, relative: &Path, warn: bool) -> Result<bool, SceneError> {
        let mtl_path = self.beside(relative);
        let library_error = |path: &Path, error: &std::io::Error| SceneError::Parse {
            path: self.path.to_path_buf(),
            line,
            kind: ParseErrorKind::MaterialLibrary {
                path: path.to_path_buf(),
                reason: error.to_string(),
            },
        };
        self.access
            .admit(&mtl_path)
            .map_err(|error| library_error(&mtl_path, &error))?;
        let identity = match std::fs::canonicalize(&mtl_path) {
            Ok(identity) => identity,
            // Exported models often travel without their `.mtl`: their shapes keep the
            // default material (or the one a scene file gives the mesh).
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
                self.missing_library = true;
                if warn {
                    self.warn_missing_library(line, &mtl_path);
                }
                return Ok(false);
            }
            Err(error) => return Err(library_error(&mtl_path, &error)),
        };
        if !self.loaded_libraries.insert(identity) {
            return Ok(true);
        }
        let text = read_file(&mtl_path).map_err(|e| match e {
            SceneError::Io { path, error } => library_error(&path, &error),
            other => other,
        })?;
        let library = mtl::parse_mtl_with(&text, &mtl_path, self.access)?;
        self.scene.warnings.extend(library.warnings);
        for material in library.materials {
            let id = MaterialId(self.scene.materials.len() as u32);
            self.material_ids.insert(material.name.clone(), id);
            self.scene.materials.push(material);
        }
        Ok(true)
    }

    fn fallback_material(&mut self) -> MaterialId {
        *self.fallback_material.get_or_insert_with(|| {
            self.scene.materials.push(Material::fallback());
            MaterialId(self.scene.materials.len() as u32 - 1)
        })
    }

    fn warn(&mut self, line_number: usize, message: &str) {
        self.scene
            .warnings
            .push(format!("{}:{line_number}: {message}", self.path.display()));
    }
}

/// Resolves a 1-based (or negative, counting back) index against `defined` elements.
#[inline]
fn resolve(token: &[u8], kind: IndexKind, defined: usize) -> Result<u32, ParseErrorKind> {
    let index =
        parse_index(token).ok_or_else(|| ParseErrorKind::BadFaceVertex(lex::show(token)))?;
    let resolved = match index {
        0 => return Err(ParseErrorKind::ZeroIndex(kind)),
        i if i > 0 => i - 1,
        i => defined as i64 + i,
    };
    if resolved < 0 || resolved >= defined as i64 || resolved > u32::MAX as i64 {
        return Err(ParseErrorKind::IndexOutOfRange {
            kind,
            index,
            defined,
        });
    }
    Ok(resolved as u32)
}

/// The group of an `s` statement: `off` or a whole number (0 means none).
fn smoothing_group(token: Option<&[u8]>) -> Result<u32, ParseErrorKind> {
    let bad = || ParseErrorKind::BadSmoothingGroup(lex::show(token.unwrap_or(b"")));
    match token {
        Some(b"off") => Ok(0),
        Some(token) => match parse_index(token) {
            // The largest value marks a group inherited from an earlier chunk.
            Some(group) if (0..i64::from(INHERITED_GROUP)).contains(&group) => Ok(group as u32),
            _ => Err(bad()),
        },
        None => Err(bad()),
    }
}

/// Parses an optionally signed decimal integer; `None` if malformed or beyond 18
/// digits (no file defines that many elements).
#[inline]
fn parse_index(token: &[u8]) -> Option<i64> {
    let (negative, digits) = match token.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, token),
    };
    if digits.is_empty() || digits.len() > 18 {
        return None;
    }
    let mut value: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        value = value * 10 + (d - b'0') as i64;
    }
    Some(if negative { -value } else { value })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parallel reader must give exactly what one chunk gives, whatever the cuts.
    #[test]
    fn chunked_parse_equals_single_chunk_parse() {
        let mut text = String::new();
        for i in 0..200 {
            text.push_str(&format!("v {i} 0 0\nv {i} 1 0\nvn 0 0 1\nv {i} 0 1\n"));
            text.push_str("f -3//-1 -2//-1 -1//-1\n");
            if i % 50 == 0 {
                text.push_str(&format!("S {i} 0 0 1\nP 0 {i} 0 1 1 1\n"));
            }
            text.push_str(&format!("f {} {} {}\n", 1 + 3 * i, 2 + 3 * i, 3));
        }
        let single = {
            let chunk = Chunk::parse(text.as_bytes(), Counts::default());
            assert!(chunk.error.is_none());
            chunk.triangles
        };
        for size in [1, 7, 64, 1000] {
            let chunks = split_into_chunks(text.as_bytes(), size);
            assert_eq!(chunks.concat(), text.as_bytes());
            let mut base = Counts::default();
            let mut triangles = Vec::new();
            for c in chunks {
                let chunk = Chunk::parse(c, base);
                assert!(chunk.error.is_none(), "{:?}", chunk.error);
                triangles.extend(chunk.triangles);
                base.add(&Counts::of(c));
            }
            assert_eq!(triangles, single, "chunk size {size}");
        }
    }

    /// Reading a file in pieces must cut it exactly where `split_into_chunks` cuts
    /// its text: the chunks, and so the reader's results, are the same.
    #[test]
    fn pieces_read_from_a_file_are_the_chunks_of_its_text() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        let mut long = String::new();
        for i in 0..3000 {
            long.push_str(&"x".repeat(i % 97));
            long.push('\n');
        }
        long.push_str(&"y".repeat(2000));
        let texts = [
            String::new(),
            "v 1 2 3".into(),
            "v 1 2 3\n".into(),
            "\n\n\n".into(),
            long.clone(),
            long + "\n",
        ];
        for text in &texts {
            std::fs::write(&path, text).unwrap();
            for size in [1, 5, 64, 300, 1000, 1 << 20] {
                let mut pieces = Vec::new();
                let mut buffer = Vec::new();
                let whole = file::read_in_pieces(&path, size, &mut buffer, |index, piece| {
                    assert_eq!(index, pieces.len());
                    pieces.push(piece);
                })
                .unwrap();
                assert!(whole.is_none());
                let expected = split_into_chunks(text.as_bytes(), size);
                assert_eq!(pieces, expected, "size {size}, text of {}", text.len());
            }
        }
        // A compressed file comes back whole, decompressed.
        use std::io::Write;
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        encoder.write_all(texts[4].as_bytes()).unwrap();
        std::fs::write(&path, encoder.finish().unwrap()).unwrap();
        let whole = file::read_in_pieces(&path, 64, &mut Vec::new(), |_, _| {
            panic!("a piece of a gzip file")
        });
        assert_eq!(whole.unwrap().unwrap(), texts[4].as_bytes());
    }

    /// A file that holds more than its size said when it was opened (it grew while
    /// read; `/proc` files say 0) is read again whole, not cut short.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_file_longer_than_its_size_is_read_whole() {
        let path = Path::new("/proc/self/status");
        let whole = file::read_in_pieces(path, 64, &mut Vec::new(), |_, _| {}).unwrap();
        let text = whole.expect("read again whole");
        assert!(
            text.starts_with(b"Name:"),
            "{}",
            String::from_utf8_lossy(&text)
        );
    }

    /// Random OBJ documents: mostly the forms mesh files use, some rarer ones, and
    /// optionally one broken line.
    struct RandomObj<R> {
        rng: R,
        /// `v`, `vt` and `vn` elements defined so far.
        defined: [usize; 3],
        /// Whether to write forms the scanner leaves to the general parser: negative
        /// indices, `f` followed by a tab.
        rare_forms: bool,
    }

    impl<R: rand::Rng> RandomObj<R> {
        fn number(&mut self) -> String {
            let rng = &mut self.rng;
            match rng.random_range(0..24) {
                0..3 => format!("{}", rng.random_range(-99..100)),
                3..13 => format!("{:.6}", rng.random_range(-1.0f64..1.0)),
                13..15 => format!("{:.9}", rng.random_range(-1.0f64..1.0)),
                15..17 => format!("{:.3e}", rng.random_range(-1e5f64..1e5)),
                17 => format!("{:E}", rng.random_range(-1e-30f64..1e-30)),
                18..20 => format!("{}", rng.random::<f32>()),
                20 => "+1.5".into(),
                21 => ".25".into(),
                22 => "-7.".into(),
                _ => ["0.1234567890123456789012", "-0", "1e-45", "16777217"]
                    [rng.random_range(0..4)]
                .into(),
            }
        }

        /// An index into the elements of kind `kind`: mostly in range, sometimes
        /// negative, rarely out of range.
        fn index(&mut self, kind: usize) -> String {
            let defined = self.defined[kind] as i64;
            match self.rng.random_range(0..1000) {
                0..100 if self.rare_forms => format!("-{}", self.rng.random_range(1..=defined)),
                999 => format!("{}", defined + self.rng.random_range(1..3)),
                _ => format!("{}", self.rng.random_range(1..=defined)),
            }
        }

        fn space(&mut self) -> &'static str {
            [" ", " ", " ", "  ", "\t"][self.rng.random_range(0..5)]
        }

        fn face(&mut self) -> String {
            let count = [3, 3, 3, 4, 5][self.rng.random_range(0..5)];
            let form = self.rng.random_range(0..4);
            let mut corners = Vec::new();
            for _ in 0..count {
                let v = self.index(0);
                corners.push(match form {
                    0 => v,
                    1 => format!("{v}/{}", self.index(1)),
                    2 => format!("{v}//{}", self.index(2)),
                    _ => format!("{v}/{}/{}", self.index(1), self.index(2)),
                });
            }
            let space = self.space();
            corners.join(space)
        }

        fn vector(&mut self) -> String {
            format!("{} {} {}", self.number(), self.number(), self.number())
        }

        fn line(&mut self) -> String {
            match self.rng.random_range(0..40) {
                0..12 => {
                    self.defined[0] += 1;
                    format!("v {}", self.vector())
                }
                12..15 => {
                    self.defined[2] += 1;
                    let space = self.space();
                    format!("vn{space}{}", self.vector())
                }
                15..18 => {
                    self.defined[1] += 1;
                    match self.rng.random_range(0..3) {
                        0 => format!("vt {}", self.number()),
                        _ => format!("vt {} {}", self.number(), self.number()),
                    }
                }
                18 => {
                    self.defined[0] += 1;
                    format!("v {} 1.0", self.vector())
                }
                19..31 => format!("f {}", self.face()),
                31 if self.rare_forms => format!("f\t{}", self.face()),
                32 => "usemtl red".into(),
                33 => "usemtl unknown name".into(),
                34 => "mtllib lib.mtl".into(),
                35 => format!("S {} 0.5", self.vector()),
                36 => "P 0 1 0 1 1 1".into(),
                37 => ["# a comment", "s 1", "s off", "s 2", "l 1 2", "p 1"]
                    [self.rng.random_range(0..6)]
                .into(),
                38 => ["o part", "f 1 2", "f 1"][self.rng.random_range(0..3)].into(),
                _ => String::new(),
            }
        }

        fn broken_line(&mut self) -> String {
            let broken = [
                "v 1 2",
                "v 1 x 3",
                "vn 1 2",
                "vt",
                "f 0 1",
                "s x",
                "f 0 1 1",
                "f 1/ 1 1",
                "f 1//1/1 1 1",
                "f a b c",
                "f 99999999999 1 1",
                "S 0 0 0 -1",
                "mtllib",
                "mtllib missing.mtl",
                "v inf 0 0",
                "P 1 2 3",
            ];
            broken[self.rng.random_range(0..broken.len())].into()
        }

        /// `lines` lines after a few elements; with `malformed`, one or two lines
        /// are broken (which problem comes first matters).
        fn document(&mut self, lines: usize, malformed: bool) -> String {
            let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n");
            self.defined = [3, 1, 1];
            self.rare_forms = self.rng.random_range(0..3) == 0;
            let broken = malformed.then(|| self.rng.random_range(0..lines));
            let also_broken = malformed.then(|| self.rng.random_range(0..lines));
            for i in 0..lines {
                let line = if broken == Some(i) || also_broken == Some(i) {
                    self.broken_line()
                } else {
                    self.line()
                };
                text.push_str(&line);
                if self.rng.random_range(0..10) == 0 {
                    text.push_str(" # trailing");
                }
                text.push_str(if self.rng.random_range(0..8) == 0 {
                    "\r\n"
                } else {
                    "\n"
                });
            }
            text
        }
    }

    /// Whether the scanner reads all of `text`, as one chunk, without the general
    /// parser's help.
    fn scanner_reads_whole(text: &[u8]) -> bool {
        let survey = survey::survey(text);
        let counts = &survey.counts;
        let mut positions = Vec::with_capacity(counts.positions);
        let mut texcoords = Vec::with_capacity(counts.texcoords);
        let mut normals = Vec::with_capacity(counts.normals);
        let mut triangles = Vec::with_capacity(counts.triangles);
        let mut triangle_normals = Vec::with_capacity(counts.triangles);
        let mut parts = Parts {
            positions: &mut positions.spare_capacity_mut()[..counts.positions],
            texcoords: &mut texcoords.spare_capacity_mut()[..counts.texcoords],
            triangle_texcoords: None,
            triangle_normals: if counts.normals > 0 {
                Some(&mut triangle_normals.spare_capacity_mut()[..counts.triangles])
            } else {
                None
            },
            normals: &mut normals.spare_capacity_mut()[..counts.normals],
            triangles: &mut triangles.spare_capacity_mut()[..counts.triangles],
        };
        let materials = vec![MaterialId(0); survey.statements.events.len() + 1];
        survey.statements.error.is_none()
            && scan::fill(
                text,
                &Counts::default(),
                &materials,
                &mut parts,
                &mut Shaping::default(),
            )
            .is_some()
    }

    fn outcome(result: Result<SceneDescription, SceneError>) -> String {
        match result {
            Ok(description) => format!("{description:?}"),
            Err(error) => format!("error: {error}"),
        }
    }

    /// The fast reader must give exactly what the general parser gives with the
    /// same chunks. (Not across chunk sizes: a chunk's "no usemtl" warning follows
    /// the chunk's other warnings, so their order can depend on the cuts.)
    #[test]
    fn fast_scanner_equals_the_general_parser_on_random_documents() {
        use rand::SeedableRng;
        let dir = tempfile::tempdir().unwrap();
        // A texture map, so that documents naming the library keep their triangles'
        // texture coordinates (in both readers) and the others do not.
        let image = std::fs::File::create(dir.path().join("red.png")).unwrap();
        let mut encoder = png::Encoder::new(image, 1, 1);
        encoder.set_color(png::ColorType::Rgb);
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(&[255, 0, 0]).unwrap();
        writer.finish().unwrap();
        std::fs::write(
            dir.path().join("lib.mtl"),
            "newmtl red\nKd 1 0 0\nmap_Kd red.png\n",
        )
        .unwrap();
        let path = dir.path().join("scene.obj");
        let mut documents = RandomObj {
            rng: rand::rngs::StdRng::seed_from_u64(11),
            defined: [0; 3],
            rare_forms: false,
        };
        let mut errors = 0;
        let mut scanned = 0;
        for document in 0..300 {
            let text = documents.document(120, document % 3 == 0);
            let text = text.as_bytes();
            scanned += usize::from(scanner_reads_whole(text));
            for size in [1, 13, 100, 700, usize::MAX] {
                let expected = outcome(parse_in_chunks(
                    text,
                    &path,
                    &FileAccess::anywhere(),
                    size,
                    Parser::General,
                ));
                if size == usize::MAX {
                    errors += usize::from(expected.starts_with("error"));
                }
                let got = outcome(parse_in_chunks(
                    text,
                    &path,
                    &FileAccess::anywhere(),
                    size,
                    Parser::Fast,
                ));
                assert_eq!(
                    got,
                    expected,
                    "chunk size {size}, document:\n{}",
                    String::from_utf8_lossy(text)
                );
            }
        }
        // Both outcomes occur often: malformed lines and out-of-range indices fail,
        // clean documents load.
        assert!((50..250).contains(&errors), "{errors} errors");
        // And the scanner reads many whole documents without help.
        assert!(scanned > 60, "{scanned} scanned");
    }
}
