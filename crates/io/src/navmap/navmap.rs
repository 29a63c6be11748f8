//! ROS occupancy-grid map files: the `map.yaml` + `map.pgm`/`map.png` pairs that ROS 1's
//! `map_server` and Nav2's `nav2_map_server` load and their `map_saver`s write.
//!
//! ```
//! use chronomap_io::navmap::{
//!     decode_map_image, decode_map_yaml, encode_map_image, encode_map_yaml, LoadSemantics,
//!     SaveOptions,
//! };
//! use chronomap_spatial::OccupancyMap;
//!
//! // A 3 x 2 map, row 0 at the bottom: free, occupied, unknown / 40 %, free, occupied.
//! let mut map = OccupancyMap::new(3, 2, 0.05, [-1.5, 2.25, 0.0]);
//! map.data = vec![0, 100, -1, 40, 0, 100];
//! let options = SaveOptions { free_thresh: 0.196, ..SaveOptions::default() };
//!
//! let yaml = encode_map_yaml("office.pgm", &map, &options)?;
//! assert_eq!(
//!     yaml,
//!     "image: office.pgm\nmode: trinary\nresolution: 0.05\norigin: [-1.5, 2.25, 0]\n\
//!      negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196"
//! );
//! let pgm = encode_map_image(&map, &options)?;
//! // The top image row is map row 1: 205 (40 % is neither free nor occupied), 254, 0.
//! assert_eq!(pgm, b"P5\n3 2\n255\n\xcd\xfe\x00\xfe\x00\xcd");
//!
//! let metadata = decode_map_yaml("office.yaml", yaml.as_bytes())?;
//! let loaded = decode_map_image("office.pgm", &pgm, &metadata, LoadSemantics::Nav2)?;
//! assert_eq!(loaded.data, [0, 100, -1, -1, 0, 100]);
//! assert_eq!((loaded.resolution, loaded.origin), (0.05, [-1.5, 2.25, 0.0]));
//!
//! // Errors name the file, the line and the key.
//! let err = decode_map_yaml("office.yaml", b"image: a.pgm\nresolution: 0.05\norigin: [1, 2]\n")
//!     .unwrap_err();
//! assert_eq!(
//!     err.to_string(),
//!     "office.yaml:3: origin: [1, 2] is invalid (expected a list of exactly 3 numbers [x, y, yaw])"
//! );
//! # Ok::<(), chronomap_io::navmap::NavMapError>(())
//! ```
//!
//! # The map
//! [`OccupancyMap`] (of `chronomap-spatial`) holds what a `nav_msgs/OccupancyGrid` message
//! holds: `data` is row-major, row 0 is the **bottom** row, values `0..=100` are occupancy in
//! percent and `-1` is unknown. Image files store rows top first, so every reader and writer
//! here flips the rows.
//!
//! # The YAML file
//! Keys (as read by `nav2_map_server` `map_io.cpp` `loadMapYaml` and ROS 1 `map_server`):
//!
//! | key | required | value |
//! |---|---|---|
//! | `image` | yes | image file, relative to the YAML file's folder unless absolute; a leading `~/` means `$HOME/` (Nav2) |
//! | `resolution` | yes | metres per cell |
//! | `origin` | yes | exactly 3 numbers `[x, y, yaw]` of the lower-left cell |
//! | `negate` | yes | an integer (non-zero: negate) or a boolean |
//! | `occupied_thresh` | yes | number |
//! | `free_thresh` | yes | number |
//! | `mode` | no | `trinary` (default), `scale` or `raw` |
//!
//! Other keys are ignored, `#` comments are allowed, and any YAML syntax for the values works
//! (flow or block sequences, quoted strings). As yaml-cpp's conversions do, numbers given as
//! quoted strings (`resolution: "0.05"`) are accepted. The file is parsed with
//! [serde-saphyr](https://docs.rs/serde-saphyr); a duplicated key, several YAML documents in
//! one file or a top level that is not a mapping are errors. A missing key or a value of the
//! wrong type is a [`NavMapError`] naming the file, the line and the key. Beyond what
//! map_server checks, `resolution` must be positive and every number finite (an infinite or
//! NaN resolution, origin or threshold cannot describe a usable map).
//!
//! # Loading: pixel to cell value ([`LoadSemantics`])
//! For each pixel, `x` is the average of its colour channels in `0..=255` units (grey images:
//! the grey value; 16-bit samples and other PGM maxvals are scaled to that range), and the
//! cell value is computed as follows (`occ` = `occupied_thresh`, `free` = `free_thresh`).
//!
//! **Nav2** (`nav2_map_server` `map_io.cpp` `loadMapFromFile`, as summarised in the project's
//! ecosystem notes from a stored copy of navigation2 main):
//! `p = 1 − x/255`, or `p = x/255` if `negate`.
//! * `trinary`: a pixel with an alpha value below fully opaque → `−1`; else `p ≥ occ` → `100`,
//!   `p ≤ free` → `0`, anything else → `−1`.
//! * `scale`: as trinary, but in-between pixels get `rint(100·(p − free)/(occ − free))` (round
//!   half to even, as C's `rint`).
//! * `raw`: `round(x)` (half away from zero, as `std::round`) if it is in `0..=100`, else `−1`;
//!   `negate` and alpha are ignored.
//!
//! **ROS 1** (`map_server` `image_loader.cpp` and the map_server wiki page; not checked against
//! a stored copy here): `negate` replaces `x` by `255 − x` first (in every mode), then
//! `p = (255 − x)/255`.
//! * `trinary`: `p > occ` → `100`, `p < free` → `0` (strict comparisons), else `−1`. If the
//!   image has an alpha channel, ROS 1 averages alpha in with the colour channels in this mode
//!   (`x = (r + g + b + a)/4`); Nav2 kept that for a while "to preserve existing behavior".
//! * `scale`: as trinary, then a fully transparent pixel (alpha 0) → `−1`, else
//!   `99·(p − free)/(occ − free)` truncated toward zero (C++ `int` conversion). The wiki gives
//!   this `99·…` formula; the noetic `image_loader.cpp` may compute `1 + 98·…` instead: this
//!   is **unverified** here.
//! * `raw`: `x` truncated to an integer and stored as `i8` by wrapping, as C++ assigns an
//!   `int` to the `int8_t` cell: `0..=127` stay, `128..=255` become `x − 256` (so 255 is `−1`,
//!   unknown, and 205 is `−51`). There is no clamping, as in ROS 1.
//!
//! Rows are flipped so that `data` row 0 is the bottom image row; width and height come from
//! the image.
//!
//! # Images read
//! * Netpbm greymaps and pixmaps: binary `P5`/`P6` and ASCII `P2`/`P3`, maxval 1 to 65535,
//!   with `#` comment lines in the header (ROS 1's map_saver writes
//!   `# CREATOR: map_saver.cpp 0.050 m/pix`). The header must be followed by exactly the
//!   pixel data it announces: a truncated file or extra bytes after the pixels are errors.
//! * PNG of any standard colour type and bit depth (via the [`png`](https://docs.rs/png)
//!   crate): palettes and `tRNS` transparency are expanded to colour and alpha, grey below 8
//!   bits is scaled to 8 bits, 16-bit samples are kept.
//!
//! Anything else (BMP, JPEG, GIF, TIFF, PBM bitmaps, PAM), which Nav2 would read through
//! GraphicsMagick, is reported as an unsupported format: convert such maps to PGM or PNG.
//! Images of more than [`MAX_MAP_CELLS`] pixels or [`MAX_IMAGE_BYTES`] decoded bytes are
//! rejected, from their header, before anything is decoded.
//!
//! # Saving (Nav2 `map_saver`)
//! [`save_map`] writes `<base>.pgm` (trinary and raw) or `<base>.png` (scale) and then
//! `<base>.yaml`, each atomically (temporary file, then rename), following
//! `nav2_map_server` `map_io.cpp` `saveMapToFile`. What was checked and how:
//!
//! * **Pixels.** The colour formulas are Nav2's; the bytes were checked against a C++
//!   program that calls GraphicsMagick++ 1.3.40 (Debian 12, 16-bit quanta, as Ubuntu's) and
//!   yaml-cpp 0.7.0 the way `saveMapToFile` does (reconstructed from the Nav2 source as
//!   remembered, not from a stored copy). Image row `y` holds map row `height − 1 − y`.
//!   * trinary: `v < 0` or `v > 100` → 205; `v ≤ rint(100·free_thresh)` → 254;
//!     `v ≥ rint(100·occupied_thresh)` → 0; otherwise 205.
//!   * scale: unknown (`v < 0` or `v > 100`) → grey 127 with alpha 0 (GraphicsMagick's
//!     `ColorGray(0.5)`, made fully transparent); known → alpha 255 and grey
//!     `⌊⌊65535·(100 − v)/100⌋ / 257⌋`, i.e. `⌊255·(100 − v)/100⌋`: GraphicsMagick
//!     truncates where one might expect rounding (v = 2 gives 249, not 250).
//!   * raw: the byte `v` for `0..=100`, 255 (GraphicsMagick's `MaxRGB`) for unknown. 255
//!     reads back as `−1` with both semantics (Nav2: outside `0..=100`; ROS 1: wraps to `−1`).
//! * **PGM**: binary `P5`, header `P5\n{width} {height}\n255\n` (GraphicsMagick writes no
//!   comment line), then `width·height` bytes: byte for byte what GraphicsMagick writes.
//! * **PNG**: 8-bit grey + alpha, as GraphicsMagick writes for `GrayscaleMatteType`. The
//!   pixel values match; the file bytes do not (GraphicsMagick adds a `bKGD` chunk and
//!   compresses differently).
//! * **YAML**: what yaml-cpp emits with `YAML::Precision(3)`: the keys `image`, `mode`,
//!   `resolution`, `origin` (flow sequence), `negate` (always 0), `occupied_thresh`,
//!   `free_thresh`, one per line; numbers formatted by [`format_g`] with 3 significant digits
//!   (the resolution is the `f32` widened to `f64`, as C++ streams do). **yaml-cpp's emitter
//!   output ends without a newline** after the last value (checked); Nav2 writes that string
//!   as it is (`std::ofstream(...) << e.c_str()`, as remembered), so the file ends with
//!   `free_thresh: 0.25` and no newline, and so do the files written here. `image` is the
//!   image's file name without folder; a name that is not obviously safe as a plain YAML
//!   scalar is written double-quoted (yaml-cpp's quoting rules differ in some corner cases,
//!   e.g. it leaves `a"b.pgm` plain; both parse to the same name).
//!   [`SaveOptions::comment`] adds `# ` lines before the first key (chronomap uses it for the
//!   prediction time); without it the text equals map_saver's byte for byte.
//! * **Checks** (as Nav2's `checkSaveParameters`): `0 ≤ free_thresh < occupied_thresh ≤ 1`.
//!   Nav2 treats a threshold of 0 as "use the default"; here 0 means 0.
//!
//! **Caution — unknown cells and `free_thresh`.** The unknown grey 205 has
//! `p = 50/255 ≈ 0.196`. With Nav2's default `free_thresh: 0.25` (the [`SaveOptions`]
//! default) that is below the free threshold, so a saved trinary map loads back with its
//! unknown cells **free**, under both semantics. ROS 1's map_saver writes `free_thresh: 0.196`
//! for this reason; use a `free_thresh` below 0.196 (e.g. 0.196, which still saves cells
//! `≤ 20` as free) to keep unknown cells unknown.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

use thiserror::Error;

use chronomap_spatial::occupancy::{FREE, InvalidMap, OCCUPIED, OccupancyMap, UNKNOWN};

use crate::yaml::{self, Prefix, Yaml};

/// Largest decoded image accepted by the readers, in bytes (samples of all channels at their
/// bit depth): 1 GiB, e.g. a 16 384 × 16 384 RGBA map.
pub const MAX_IMAGE_BYTES: u64 = 1 << 30;

/// Most pixels (cells) of a map image: 2^26 = 67 108 864, e.g. 8192 × 8192 cells (410 m square
/// at 5 cm). Checked from the image header before anything is decoded, so a small file that
/// announces a huge image (a 948 KB PNG of 30 000 × 30 000) costs neither memory nor time.
pub const MAX_MAP_CELLS: u64 = 1 << 26;

/// Longest image file name a map YAML may give, in bytes (the usual `PATH_MAX`).
const MAX_IMAGE_NAME_BYTES: usize = 4096;

/// Longest excerpt of file content quoted in an error message, in characters.
const MAX_QUOTED_CHARS: usize = 40;

/// How image pixels and cell values correspond (the YAML key `mode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MapMode {
    /// Free, occupied or unknown (three grey levels).
    #[default]
    Trinary,
    /// Occupancy as a grey gradient, unknown as transparency (PNG).
    Scale,
    /// Cell values stored as pixel values.
    Raw,
}

impl MapMode {
    /// `"trinary"`, `"scale"` or `"raw"`, as in the YAML file.
    pub fn as_str(self) -> &'static str {
        match self {
            MapMode::Trinary => "trinary",
            MapMode::Scale => "scale",
            MapMode::Raw => "raw",
        }
    }

    /// The mode named `name` in a YAML file (case-sensitive, as map_server).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "trinary" => Some(MapMode::Trinary),
            "scale" => Some(MapMode::Scale),
            "raw" => Some(MapMode::Raw),
            _ => None,
        }
    }

    /// Extension of the image [`save_map`] writes in this mode: `"png"` for scale (it needs
    /// transparency), `"pgm"` otherwise (map_saver's defaults).
    pub fn image_extension(self) -> &'static str {
        match self {
            MapMode::Scale => "png",
            MapMode::Trinary | MapMode::Raw => "pgm",
        }
    }
}

impl fmt::Display for MapMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How [`save_map`] writes a map.
#[derive(Clone, Debug, PartialEq)]
pub struct SaveOptions {
    /// Image mode (default trinary).
    pub mode: MapMode,
    /// Cells at or above `rint(100 · occupied_thresh)` are saved as occupied in trinary mode;
    /// also written to the YAML file. Default 0.65 (map_saver's).
    pub occupied_thresh: f64,
    /// Cells at or below `rint(100 · free_thresh)` are saved as free in trinary mode; also
    /// written to the YAML file. Default 0.25 (Nav2 map_saver's), which makes the unknown grey
    /// load back as free: see the [module docs](self#saving-nav2-map_saver).
    pub free_thresh: f64,
    /// Text written as `# ` comment lines before the first YAML key (one per line of the
    /// text); `None` writes exactly what map_saver writes.
    pub comment: Option<String>,
}

impl Default for SaveOptions {
    fn default() -> Self {
        SaveOptions {
            mode: MapMode::Trinary,
            occupied_thresh: 0.65,
            free_thresh: 0.25,
            comment: None,
        }
    }
}

impl SaveOptions {
    fn check(&self) -> Result<(), NavMapErrorKind> {
        let (free, occupied) = (self.free_thresh, self.occupied_thresh);
        if !(0.0 <= free && free < occupied && occupied <= 1.0) {
            return Err(NavMapErrorKind::InvalidOptions {
                reason: format!(
                    "thresholds must satisfy 0 <= free_thresh < occupied_thresh <= 1, \
                     got free_thresh {free} and occupied_thresh {occupied}"
                ),
            });
        }
        Ok(())
    }
}

/// The files written by [`save_map`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SavedMap {
    /// The YAML file (`<base>.yaml`).
    pub yaml: PathBuf,
    /// The image file (`<base>.pgm` or `<base>.png`).
    pub image: PathBuf,
}

/// Which map_server's rules turn pixels into cell values (see the
/// [module docs](self#loading-pixel-to-cell-value-loadsemantics)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LoadSemantics {
    /// Nav2's `nav2_map_server`: inclusive thresholds, `rint` scaling, clamped raw values.
    #[default]
    Nav2,
    /// ROS 1's `map_server`: strict thresholds, `99·…` scaling, wrapped raw values.
    Ros1,
}

/// The content of a map YAML file.
#[derive(Clone, Debug, PartialEq)]
pub struct MapMetadata {
    /// The image file as written in the YAML file (see [`image_path`]).
    pub image: String,
    /// Image mode (trinary if the file has no `mode`).
    pub mode: MapMode,
    /// Metres per cell.
    pub resolution: f64,
    /// `[x, y, yaw]` of the lower-left cell.
    pub origin: [f64; 3],
    /// Whether dark pixels are free (`negate` non-zero or true).
    pub negate: bool,
    /// Occupancy probability at or above which (Nav2; above which, ROS 1) a cell is occupied.
    pub occupied_thresh: f64,
    /// Occupancy probability at or below which (Nav2; below which, ROS 1) a cell is free.
    pub free_thresh: f64,
}

/// What is wrong with a map file or map (the part of a [`NavMapError`] after `file:line:`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum NavMapErrorKind {
    /// The file could not be read or written.
    #[error("cannot {action}: {io}")]
    Io {
        /// What was being done (`"read"`, `"create a temporary file for"`, ...).
        action: &'static str,
        /// The underlying error.
        io: io::Error,
    },
    /// The image named in a YAML file could not be read (the error names the image).
    #[error("cannot read the image named in {yaml}: {io}")]
    ImageUnreadable {
        /// The YAML file that names the image.
        yaml: String,
        /// The underlying error.
        io: io::Error,
    },
    /// The YAML file is not valid YAML, has several documents or is not a mapping.
    #[error("not a map_server YAML file: {message}")]
    Yaml {
        /// The parser's message.
        message: String,
    },
    /// A required key is missing.
    #[error("missing required key `{key}`")]
    MissingKey {
        /// The key.
        key: &'static str,
    },
    /// A key has a value of the wrong type or outside its range.
    #[error("{key}: {value} is invalid (expected {expected})")]
    InvalidValue {
        /// The key.
        key: &'static str,
        /// The value as YAML (shortened if long).
        value: String,
        /// What the key needs.
        expected: &'static str,
    },
    /// The image file has no bytes at all.
    #[error("the image file is empty (0 bytes)")]
    EmptyImage,
    /// The image is in a format this reader does not read.
    #[error(
        "unsupported image format: {format} (map images are read as PGM/PPM (P2, P3, P5, P6) or PNG)"
    )]
    UnsupportedImageFormat {
        /// The format recognised, or the first bytes.
        format: String,
    },
    /// The image is malformed (bad header, sample out of range, invalid PNG, ...).
    #[error("malformed {format} image: {reason}")]
    MalformedImage {
        /// `"PGM"`, `"PPM"` or `"PNG"`.
        format: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The image ends before the pixel data its header announces.
    #[error(
        "truncated image: the header announces {expected} {unit} of pixel data but only {actual} follow"
    )]
    TruncatedImage {
        /// Announced amount.
        expected: u64,
        /// Amount present.
        actual: u64,
        /// `"bytes"` or `"samples"`.
        unit: &'static str,
    },
    /// More data follows the pixels than the header announces.
    #[error(
        "unexpected data after the pixels: the header announces {expected} {unit} of pixel \
         data but {actual} follow"
    )]
    TrailingData {
        /// Announced amount.
        expected: u64,
        /// Amount present.
        actual: u64,
        /// `"bytes"` or `"samples"`.
        unit: &'static str,
    },
    /// The image has more than [`MAX_MAP_CELLS`] pixels, is larger than [`MAX_IMAGE_BYTES`]
    /// once decoded, or is empty.
    #[error("image of {width} x {height} pixels is {reason}")]
    ImageSize {
        /// Width from the header.
        width: u64,
        /// Height from the header.
        height: u64,
        /// `"empty"` or why it is too large.
        reason: String,
    },
    /// The map cannot be written (empty, data length not `width · height`, non-finite
    /// numbers).
    #[error("invalid map: {reason}")]
    InvalidMap {
        /// What is wrong.
        reason: String,
    },
    /// The save options are inconsistent.
    #[error("invalid save options: {reason}")]
    InvalidOptions {
        /// What is wrong.
        reason: String,
    },
    /// The base path given to [`save_map`] cannot name the files.
    #[error("invalid map path: {reason}")]
    InvalidPath {
        /// What is wrong.
        reason: &'static str,
    },
}

impl From<InvalidMap> for NavMapErrorKind {
    fn from(e: InvalidMap) -> Self {
        NavMapErrorKind::InvalidMap { reason: e.reason }
    }
}

/// Why a map could not be loaded, decoded, encoded or saved: the file (when there is one),
/// the 1-based line (for YAML values) and the problem.
///
/// Displays as `file:line: problem`, e.g.
/// `maps/office.yaml:3: resolution: "fine" is invalid (expected a number)`, or
/// `file: problem`, or the problem alone for maps in memory.
#[derive(Debug, Error)]
#[error("{}{kind}", Prefix(.file.as_deref(), *.line))]
pub struct NavMapError {
    file: Option<String>,
    line: Option<u64>,
    kind: NavMapErrorKind,
}

impl NavMapError {
    fn new(kind: NavMapErrorKind) -> Self {
        NavMapError {
            file: None,
            line: None,
            kind,
        }
    }

    fn in_file(name: &str, kind: NavMapErrorKind) -> Self {
        NavMapError {
            file: Some(name.to_owned()),
            line: None,
            kind,
        }
    }

    fn at(name: &str, line: u64, kind: NavMapErrorKind) -> Self {
        NavMapError {
            file: Some(name.to_owned()),
            line: (line > 0).then_some(line),
            kind,
        }
    }

    /// The file (as given, or the path written or read), if the error concerns one.
    pub fn file(&self) -> Option<&str> {
        self.file.as_deref()
    }

    /// The 1-based line of the YAML value concerned, if known.
    pub fn line(&self) -> Option<u64> {
        self.line
    }

    /// The YAML key concerned, if any.
    pub fn key(&self) -> Option<&'static str> {
        match self.kind {
            NavMapErrorKind::MissingKey { key } | NavMapErrorKind::InvalidValue { key, .. } => {
                Some(key)
            }
            _ => None,
        }
    }

    /// What is wrong.
    pub fn kind(&self) -> &NavMapErrorKind {
        &self.kind
    }
}

/// Formats `value` as C's `printf("%.{precision}g")` and C++'s
/// `std::cout << std::setprecision(precision) << value` do, which is how yaml-cpp writes
/// numbers under `YAML::Precision(precision)`.
///
/// `precision` significant digits (0 counts as 1), correctly rounded (ties to even, as
/// glibc); trailing zeros and a trailing decimal point are removed; scientific notation
/// (`1.23e+05`, at least two exponent digits) when the decimal exponent is below −4 or at
/// least `precision`. Non-finite values print as `nan`, `inf`, `-inf`.
///
/// ```
/// use chronomap_io::navmap::format_g;
///
/// assert_eq!(format_g(0.05, 3), "0.05");
/// assert_eq!(format_g(12.345, 3), "12.3");
/// assert_eq!(format_g(1e-4, 3), "0.0001");
/// assert_eq!(format_g(123456.0, 3), "1.23e+05");
/// assert_eq!(format_g(f64::from(0.05f32), 3), "0.05");
/// ```
pub fn format_g(value: f64, precision: usize) -> String {
    let precision = precision.max(1);
    if value.is_nan() {
        return "nan".to_owned();
    }
    if value.is_infinite() {
        return if value > 0.0 { "inf" } else { "-inf" }.to_owned();
    }
    if value == 0.0 {
        return if value.is_sign_negative() { "-0" } else { "0" }.to_owned();
    }
    // Rust's `{:e}` and `{:.N}` round correctly (ties to even on exact binary ties), as glibc.
    let scientific = format!("{:.*e}", precision - 1, value);
    let (mantissa, exponent) = scientific
        .split_once('e')
        .expect("`{:e}` output has an exponent");
    let exponent: i32 = exponent.parse().expect("`{:e}` exponent is an integer");
    if exponent < -4 || exponent >= precision as i32 {
        let sign = if exponent < 0 { '-' } else { '+' };
        format!(
            "{}e{sign}{:02}",
            strip_fraction_zeros(mantissa),
            exponent.unsigned_abs()
        )
    } else {
        let decimals = (precision as i32 - 1 - exponent) as usize;
        strip_fraction_zeros(&format!("{value:.decimals$}")).to_owned()
    }
}

fn strip_fraction_zeros(number: &str) -> &str {
    if number.contains('.') {
        number.trim_end_matches('0').trim_end_matches('.')
    } else {
        number
    }
}

// ---------------------------------------------------------------------------------------------
// Saving

/// Writes `map` as map_saver does: `<base>.pgm` (trinary, raw) or `<base>.png` (scale), then
/// `<base>.yaml` naming it (see the [module docs](self#saving-nav2-map_saver)).
///
/// The extensions are appended to `base` (`maps/office` → `maps/office.yaml`,
/// `maps/office.pgm`). Each file is written atomically, the image first, so the YAML file
/// never names a missing image.
///
/// # Errors
/// [`NavMapErrorKind::InvalidMap`], [`InvalidOptions`](NavMapErrorKind::InvalidOptions),
/// [`InvalidPath`](NavMapErrorKind::InvalidPath) (`base` has no file name, or one that is not
/// UTF-8) or [`Io`](NavMapErrorKind::Io) naming the file that could not be written.
pub fn save_map(
    base: &Path,
    map: &OccupancyMap,
    options: &SaveOptions,
) -> Result<SavedMap, NavMapError> {
    let base_name = base.display().to_string();
    let invalid_path =
        |reason| NavMapError::in_file(&base_name, NavMapErrorKind::InvalidPath { reason });
    let file_name = base
        .file_name()
        .ok_or_else(|| invalid_path("it does not end in a file name"))?;
    let file_name = file_name
        .to_str()
        .ok_or_else(|| invalid_path("the file name is not valid UTF-8"))?;
    let image_name = format!("{file_name}.{}", options.mode.image_extension());
    let image = base.with_file_name(&image_name);
    let yaml = base.with_file_name(format!("{file_name}.yaml"));

    let image_bytes =
        encode_map_image(map, options).map_err(|e| e.with_file(&image.display().to_string()))?;
    let yaml_text = encode_map_yaml(&image_name, map, options)
        .map_err(|e| e.with_file(&yaml.display().to_string()))?;
    write_file(&image, &image_bytes)?;
    write_file(&yaml, yaml_text.as_bytes())?;
    Ok(SavedMap { yaml, image })
}

impl NavMapError {
    fn with_file(mut self, name: &str) -> Self {
        self.file = Some(name.to_owned());
        self
    }
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), NavMapError> {
    crate::atomic::write_atomically(path, bytes).map_err(|failure| {
        NavMapError::in_file(
            &path.display().to_string(),
            NavMapErrorKind::Io {
                action: failure.action,
                io: failure.io,
            },
        )
    })
}

/// The image file [`save_map`] writes for `map`: binary PGM for trinary and raw, 8-bit
/// grey + alpha PNG for scale.
///
/// ```
/// use chronomap_io::navmap::{encode_map_image, MapMode, SaveOptions};
/// use chronomap_spatial::OccupancyMap;
///
/// let mut map = OccupancyMap::new(4, 1, 0.1, [0.0; 3]);
/// map.data = vec![0, 42, 100, -1];
/// let raw = SaveOptions { mode: MapMode::Raw, ..SaveOptions::default() };
/// assert_eq!(encode_map_image(&map, &raw)?, b"P5\n4 1\n255\n\x00\x2a\x64\xff");
/// # Ok::<(), chronomap_io::navmap::NavMapError>(())
/// ```
///
/// # Errors
/// [`NavMapErrorKind::InvalidMap`] or [`InvalidOptions`](NavMapErrorKind::InvalidOptions).
pub fn encode_map_image(map: &OccupancyMap, options: &SaveOptions) -> Result<Vec<u8>, NavMapError> {
    map.check()
        .map_err(|e| NavMapError::new(NavMapErrorKind::from(e)))?;
    options.check().map_err(NavMapError::new)?;
    let free = (100.0 * options.free_thresh).round_ties_even() as i32;
    let occupied = (100.0 * options.occupied_thresh).round_ties_even() as i32;
    let known = |v: i8| (0..=100).contains(&v);
    match options.mode {
        MapMode::Trinary => Ok(encode_pgm(map, |v| {
            let v = i32::from(v);
            if !(0..=100).contains(&v) {
                205
            } else if v <= free {
                254
            } else if occupied <= v {
                0
            } else {
                205
            }
        })),
        MapMode::Raw => Ok(encode_pgm(map, |v| {
            if known(v) {
                graphicsmagick_grey(f64::from(v) / 255.0)
            } else {
                255
            }
        })),
        MapMode::Scale => encode_scale_png(map),
    }
}

/// The 8-bit grey GraphicsMagick (16-bit quanta) writes for a `ColorGray(shade)` pixel:
/// the quantum is `shade · 65535` truncated, the 8-bit value the quantum divided by 257.
fn graphicsmagick_grey(shade: f64) -> u8 {
    (((shade * 65535.0) as u32) / 257) as u8
}

/// Image rows top first: image row `y` is map row `height - 1 - y`.
fn image_rows(map: &OccupancyMap) -> impl Iterator<Item = &[i8]> {
    map.data.chunks_exact(map.width as usize).rev()
}

fn encode_pgm(map: &OccupancyMap, pixel: impl Fn(i8) -> u8) -> Vec<u8> {
    let header = format!("P5\n{} {}\n255\n", map.width, map.height);
    let mut bytes = Vec::with_capacity(header.len() + map.data.len());
    bytes.extend_from_slice(header.as_bytes());
    for row in image_rows(map) {
        bytes.extend(row.iter().map(|&v| pixel(v)));
    }
    bytes
}

fn encode_scale_png(map: &OccupancyMap) -> Result<Vec<u8>, NavMapError> {
    let mut pixels = Vec::with_capacity(2 * map.data.len());
    for row in image_rows(map) {
        for &v in row {
            if (0..=100).contains(&v) {
                pixels.push(graphicsmagick_grey((100.0 - f64::from(v)) / 100.0));
                pixels.push(255);
            } else {
                pixels.push(graphicsmagick_grey(0.5));
                pixels.push(0);
            }
        }
    }
    let png_error = |e: png::EncodingError| {
        NavMapError::new(NavMapErrorKind::InvalidMap {
            reason: format!("cannot encode as PNG: {e}"),
        })
    };
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, map.width, map.height);
    encoder.set_color(png::ColorType::GrayscaleAlpha);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(png_error)?;
    writer.write_image_data(&pixels).map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok(bytes)
}

/// The YAML text [`save_map`] writes for `map` with image file name `image_name`: yaml-cpp's
/// output as map_saver produces it, without a final newline, after the
/// [`comment`](SaveOptions::comment) lines if any.
///
/// ```
/// use chronomap_io::navmap::{encode_map_yaml, MapMode, SaveOptions};
/// use chronomap_spatial::OccupancyMap;
///
/// let map = OccupancyMap::new(1, 1, 0.05, [-12.345, 123456.0, 0.0]);
/// let options = SaveOptions {
///     mode: MapMode::Scale,
///     comment: Some("predicted for 2016-03-21T12:00:00Z".into()),
///     ..SaveOptions::default()
/// };
/// assert_eq!(
///     encode_map_yaml("office.png", &map, &options)?,
///     "# predicted for 2016-03-21T12:00:00Z\nimage: office.png\nmode: scale\n\
///      resolution: 0.05\norigin: [-12.3, 1.23e+05, 0]\nnegate: 0\n\
///      occupied_thresh: 0.65\nfree_thresh: 0.25"
/// );
/// # Ok::<(), chronomap_io::navmap::NavMapError>(())
/// ```
///
/// # Errors
/// [`NavMapErrorKind::InvalidMap`] or [`InvalidOptions`](NavMapErrorKind::InvalidOptions).
pub fn encode_map_yaml(
    image_name: &str,
    map: &OccupancyMap,
    options: &SaveOptions,
) -> Result<String, NavMapError> {
    map.check()
        .map_err(|e| NavMapError::new(NavMapErrorKind::from(e)))?;
    options.check().map_err(NavMapError::new)?;
    let mut text = String::new();
    if let Some(comment) = &options.comment {
        for line in comment.split('\n') {
            let line = line.strip_suffix('\r').unwrap_or(line);
            if line.is_empty() {
                text.push_str("#\n");
            } else {
                text.push_str("# ");
                text.push_str(line);
                text.push('\n');
            }
        }
    }
    let g = |v: f64| format_g(v, 3);
    let [x, y, yaw] = map.origin;
    text.push_str(&format!(
        "image: {}\nmode: {}\nresolution: {}\norigin: [{}, {}, {}]\nnegate: 0\n\
         occupied_thresh: {}\nfree_thresh: {}",
        yaml_string(image_name),
        options.mode,
        g(f64::from(map.resolution)),
        g(x),
        g(y),
        g(yaw),
        g(options.occupied_thresh),
        g(options.free_thresh),
    ));
    Ok(text)
}

/// `text` as a YAML scalar: plain if that is obviously safe, else double-quoted.
fn yaml_string(text: &str) -> String {
    let safe_char = |c: char| c.is_alphanumeric() || "._-+,()=~ ".contains(c);
    let plain = !text.is_empty()
        && text.chars().all(safe_char)
        && !text.starts_with([' ', '-', '~'])
        && !text.ends_with(' ')
        && !matches!(
            text,
            "true" | "false" | "null" | "yes" | "no" | "on" | "off" | "True" | "False" | "Null"
        );
    if plain && text.parse::<f64>().is_err() {
        return text.to_owned();
    }
    yaml::double_quoted(text)
}

// ---------------------------------------------------------------------------------------------
// Loading

/// Reads a map_server YAML file and the image it names, turning pixels into cells with the
/// given semantics (see the [module docs](self)).
///
/// ```no_run
/// use chronomap_io::navmap::{load_map, LoadSemantics};
///
/// let map = load_map("maps/office.yaml".as_ref(), LoadSemantics::Nav2)?;
/// println!("{} x {} cells of {} m", map.width, map.height, map.resolution);
/// # Ok::<(), chronomap_io::navmap::NavMapError>(())
/// ```
///
/// # Errors
/// As [`read_map_yaml`] and [`decode_map_image`] (naming the image file), or
/// [`NavMapErrorKind::ImageUnreadable`] if the image cannot be read.
pub fn load_map(yaml: &Path, semantics: LoadSemantics) -> Result<OccupancyMap, NavMapError> {
    let metadata = read_map_yaml(yaml)?;
    let image = image_path(yaml, &metadata.image);
    let image_name = image.display().to_string();
    let bytes = crate::bounded::read(&image).map_err(|io| {
        NavMapError::in_file(
            &image_name,
            NavMapErrorKind::ImageUnreadable {
                yaml: yaml.display().to_string(),
                io,
            },
        )
    })?;
    decode_map_image(&image_name, &bytes, &metadata, semantics)
}

/// Reads and checks a map_server YAML file.
///
/// # Errors
/// [`NavMapErrorKind::Io`] if it cannot be read, else as [`decode_map_yaml`]; all errors name
/// `path`.
pub fn read_map_yaml(path: &Path) -> Result<MapMetadata, NavMapError> {
    let name = path.display().to_string();
    let bytes = crate::bounded::read(path)
        .map_err(|io| NavMapError::in_file(&name, NavMapErrorKind::Io { action: "read", io }))?;
    decode_map_yaml(&name, &bytes)
}

/// Where the image named `image` in the YAML file `yaml` is: `image` itself if absolute,
/// `$HOME/rest` for `~/rest` (as Nav2 expands it; unchanged if `HOME` is not set), otherwise
/// relative to the YAML file's folder.
pub fn image_path(yaml: &Path, image: &str) -> PathBuf {
    if let Some(rest) = image.strip_prefix("~/")
        && let Some(home) = std::env::var_os("HOME")
    {
        return PathBuf::from(home).join(rest);
    }
    let image = Path::new(image);
    if image.is_absolute() {
        return image.to_owned();
    }
    match yaml.parent() {
        Some(dir) => dir.join(image),
        None => image.to_owned(),
    }
}

/// The keys of a map YAML file, in map_saver's order.
const KEYS: [&str; 7] = [
    "image",
    "mode",
    "resolution",
    "origin",
    "negate",
    "occupied_thresh",
    "free_thresh",
];

/// Parses and checks the text of a map_server YAML file; `name` is used in errors.
///
/// # Errors
/// [`NavMapErrorKind::Yaml`] (with the line, when the parser knows it),
/// [`MissingKey`](NavMapErrorKind::MissingKey) or
/// [`InvalidValue`](NavMapErrorKind::InvalidValue) (with the line of the value).
pub fn decode_map_yaml(name: &str, text: &[u8]) -> Result<MapMetadata, NavMapError> {
    let root = yaml::parse(text, false).map_err(|e| {
        NavMapError::at(
            name,
            e.line.unwrap_or(0),
            NavMapErrorKind::Yaml { message: e.message },
        )
    })?;
    let raw = RawYaml::of(&root.value).ok_or_else(|| {
        NavMapError::at(
            name,
            root.referenced.line(),
            NavMapErrorKind::Yaml {
                message: "the top level is not a mapping of keys to values".to_owned(),
            },
        )
    })?;
    let value_of = |key: &'static str| {
        let index = KEYS.iter().position(|k| *k == key).expect("a known key");
        match raw.values[index] {
            Some((line, node)) => Ok((line, node)),
            None => Err(NavMapError::in_file(
                name,
                NavMapErrorKind::MissingKey { key },
            )),
        }
    };
    let value = value_of;
    let invalid = |key: &'static str, line: u64, node: &Yaml, expected: &'static str| {
        NavMapError::at(
            name,
            line,
            NavMapErrorKind::InvalidValue {
                key,
                value: shorten(&node.listed().to_string()),
                expected,
            },
        )
    };
    let number = |key: &'static str| {
        let (line, node) = value(key)?;
        as_number(node).ok_or_else(|| invalid(key, line, node, "a finite number"))
    };

    let (line, node) = value("image")?;
    let image = match node {
        Yaml::Str(s) if s.len() > MAX_IMAGE_NAME_BYTES => {
            return Err(invalid(
                "image",
                line,
                node,
                "a file name of at most 4096 bytes",
            ));
        }
        Yaml::Str(s) if !s.is_empty() => s.clone(),
        _ => return Err(invalid("image", line, node, "a file name")),
    };
    let resolution = number("resolution")?;
    if resolution <= 0.0 {
        let (line, node) = value("resolution")?;
        return Err(invalid("resolution", line, node, "a positive number"));
    }
    let (line, node) = value("origin")?;
    const ORIGIN: &str = "a list of exactly 3 numbers [x, y, yaw]";
    let origin = match node {
        Yaml::Seq(items) if items.len() == 3 => {
            let mut origin = [0.0; 3];
            for (slot, item) in origin.iter_mut().zip(items) {
                *slot =
                    as_number(&item.value).ok_or_else(|| invalid("origin", line, node, ORIGIN))?;
            }
            origin
        }
        _ => return Err(invalid("origin", line, node, ORIGIN)),
    };
    let (line, node) = value("negate")?;
    let negate = match node {
        Yaml::Bool(b) => *b,
        Yaml::Int(i) => *i != 0,
        Yaml::Str(s) => match s.trim() {
            "true" => true,
            "false" => false,
            t => t
                .parse::<i64>()
                .map(|i| i != 0)
                .map_err(|_| invalid("negate", line, node, "0, 1, true or false"))?,
        },
        _ => return Err(invalid("negate", line, node, "0, 1, true or false")),
    };
    let threshold = |key: &'static str| {
        let value = number(key)?;
        if (0.0..=1.0).contains(&value) {
            Ok(value)
        } else {
            let (line, node) = value_of(key)?;
            Err(invalid(key, line, node, "a number in [0, 1]"))
        }
    };
    let occupied_thresh = threshold("occupied_thresh")?;
    let free_thresh = threshold("free_thresh")?;
    if occupied_thresh < free_thresh {
        let (line, node) = value_of("occupied_thresh")?;
        return Err(invalid(
            "occupied_thresh",
            line,
            node,
            "a number >= free_thresh (a cell cannot be both occupied and free)",
        ));
    }
    let mode = match value("mode") {
        Err(_) => MapMode::Trinary,
        Ok((line, node)) => match node {
            Yaml::Str(s) => MapMode::from_name(s),
            _ => None,
        }
        .ok_or_else(|| invalid("mode", line, node, "trinary, scale or raw"))?,
    };
    Ok(MapMetadata {
        image,
        mode,
        resolution,
        origin,
        negate,
        occupied_thresh,
        free_thresh,
    })
}

/// A finite number: a YAML number or a string holding one (yaml-cpp converts both).
fn as_number(node: &Yaml) -> Option<f64> {
    let number = match node {
        Yaml::Int(i) => *i as f64,
        Yaml::Float(f) => *f,
        Yaml::Str(s) => s.trim().parse().ok()?,
        _ => return None,
    };
    number.is_finite().then_some(number)
}

/// The known keys of a map YAML file with the line and value of each one present.
#[derive(Default)]
struct RawYaml<'a> {
    values: [Option<(u64, &'a Yaml)>; KEYS.len()],
}

impl<'a> RawYaml<'a> {
    /// The known keys of the top level, or `None` if it is not a mapping. An empty file (or
    /// one with only comments) is an empty mapping: every required key is then reported
    /// missing.
    fn of(top: &'a Yaml) -> Option<Self> {
        let mut raw = RawYaml::default();
        match top {
            Yaml::Null => {}
            Yaml::Map(entries) => {
                for (key, value) in entries {
                    if let Some(i) = KEYS.iter().position(|k| k == key) {
                        raw.values[i] = Some((value.referenced.line(), &value.value));
                    }
                }
            }
            _ => return None,
        }
        Some(raw)
    }
}

/// Text for an error message, shortened to [`MAX_QUOTED_CHARS`] characters.
fn shorten(text: &str) -> String {
    crate::text::shorten(text, MAX_QUOTED_CHARS)
}

/// Decodes a map image (PGM/PPM or PNG bytes) into cells, with the mode, thresholds,
/// `negate`, resolution and origin of `metadata`; `name` is used in errors.
///
/// # Errors
/// [`NavMapErrorKind::UnsupportedImageFormat`],
/// [`MalformedImage`](NavMapErrorKind::MalformedImage),
/// [`TruncatedImage`](NavMapErrorKind::TruncatedImage),
/// [`TrailingData`](NavMapErrorKind::TrailingData),
/// [`ImageSize`](NavMapErrorKind::ImageSize) or [`EmptyImage`](NavMapErrorKind::EmptyImage),
/// all naming `name`.
pub fn decode_map_image(
    name: &str,
    bytes: &[u8],
    metadata: &MapMetadata,
    semantics: LoadSemantics,
) -> Result<OccupancyMap, NavMapError> {
    let raster = decode_raster(bytes).map_err(|kind| NavMapError::in_file(name, kind))?;
    let width = raster.width as usize;
    let mut data = vec![UNKNOWN; raster.pixel_count()];
    for (y, row) in data.chunks_exact_mut(width).rev().enumerate() {
        for (x, cell) in row.iter_mut().enumerate() {
            let pixel = raster.pixel(y * width + x);
            *cell = match semantics {
                LoadSemantics::Nav2 => nav2_cell(metadata, &pixel),
                LoadSemantics::Ros1 => ros1_cell(metadata, &pixel),
            };
        }
    }
    Ok(OccupancyMap {
        width: raster.width,
        height: raster.height,
        resolution: metadata.resolution as f32,
        origin: metadata.origin,
        data,
    })
}

/// One pixel in `0..=255` units.
struct Pixel {
    /// Average of the colour channels.
    colour: f64,
    /// The alpha channel, if the image has one.
    alpha: Option<f64>,
    /// Whether the pixel is fully opaque (alpha at the maximum, or no alpha channel).
    opaque: bool,
}

fn nav2_cell(m: &MapMetadata, pixel: &Pixel) -> i8 {
    if m.mode == MapMode::Raw {
        let value = pixel.colour.round();
        return if (0.0..=100.0).contains(&value) {
            value as i8
        } else {
            UNKNOWN
        };
    }
    if !pixel.opaque {
        return UNKNOWN;
    }
    let shade = pixel.colour / 255.0;
    let p = if m.negate { shade } else { 1.0 - shade };
    if p >= m.occupied_thresh {
        OCCUPIED
    } else if p <= m.free_thresh {
        FREE
    } else if m.mode == MapMode::Trinary {
        UNKNOWN
    } else {
        // In between, so free < p < occupied and the quotient is in (0, 1).
        ((p - m.free_thresh) / (m.occupied_thresh - m.free_thresh) * 100.0).round_ties_even() as i8
    }
}

fn ros1_cell(m: &MapMetadata, pixel: &Pixel) -> i8 {
    let mut x = match (m.mode, pixel.alpha) {
        (MapMode::Trinary, Some(alpha)) => (3.0 * pixel.colour + alpha) / 4.0,
        _ => pixel.colour,
    };
    if m.negate {
        x = 255.0 - x;
    }
    if m.mode == MapMode::Raw {
        // `int value = color_avg;` then the int8 cell: truncate, then wrap.
        return x as i32 as i8;
    }
    let p = (255.0 - x) / 255.0;
    if p > m.occupied_thresh {
        OCCUPIED
    } else if p < m.free_thresh {
        FREE
    } else if m.mode == MapMode::Trinary || pixel.alpha.is_some_and(|a| a < 1.0) {
        UNKNOWN
    } else {
        let ratio = (p - m.free_thresh) / (m.occupied_thresh - m.free_thresh);
        (99.0 * ratio) as i32 as i8
    }
}

/// Decoded image samples.
struct Raster {
    width: u32,
    height: u32,
    /// Samples per pixel: 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA.
    channels: usize,
    /// Largest sample value.
    maxval: u32,
    samples: Samples,
}

enum Samples {
    Eight(Vec<u8>),
    Sixteen(Vec<u16>),
}

impl Raster {
    fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    fn sample(&self, i: usize) -> u32 {
        match &self.samples {
            Samples::Eight(s) => u32::from(s[i]),
            Samples::Sixteen(s) => u32::from(s[i]),
        }
    }

    /// Pixel `i` (row-major, top row first).
    fn pixel(&self, i: usize) -> Pixel {
        let base = i * self.channels;
        let (colours, alpha) = match self.channels {
            1 => (1, None),
            2 => (1, Some(self.sample(base + 1))),
            3 => (3, None),
            _ => (3, Some(self.sample(base + 3))),
        };
        let sum: u32 = (0..colours).map(|c| self.sample(base + c)).sum();
        let to_255 = |v: f64| {
            if self.maxval == 255 {
                v
            } else {
                v * 255.0 / f64::from(self.maxval)
            }
        };
        Pixel {
            colour: to_255(f64::from(sum) / colours as f64),
            alpha: alpha.map(|a| to_255(f64::from(a))),
            opaque: alpha.is_none_or(|a| a == self.maxval),
        }
    }
}

fn decode_raster(bytes: &[u8]) -> Result<Raster, NavMapErrorKind> {
    let unsupported = |format: &str| {
        Err(NavMapErrorKind::UnsupportedImageFormat {
            format: format.to_owned(),
        })
    };
    match bytes {
        [] => Err(NavMapErrorKind::EmptyImage),
        [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n', ..] => decode_png(bytes),
        [b'P', b'2' | b'3' | b'5' | b'6', ..] => decode_pnm(bytes),
        [b'P', b'1' | b'4', ..] => unsupported("PBM bitmap (P1/P4)"),
        [b'P', b'7', ..] => unsupported("PAM (P7)"),
        [b'B', b'M', ..] => unsupported("BMP"),
        [0xff, 0xd8, 0xff, ..] => unsupported("JPEG"),
        [b'G', b'I', b'F', b'8', ..] => unsupported("GIF"),
        [b'I', b'I', 42, 0, ..] | [b'M', b'M', 0, 42, ..] => unsupported("TIFF"),
        [
            b'R',
            b'I',
            b'F',
            b'F',
            _,
            _,
            _,
            _,
            b'W',
            b'E',
            b'B',
            b'P',
            ..,
        ] => unsupported("WebP"),
        _ => unsupported(&format!(
            "unknown (the file starts with {:?})",
            shorten(&String::from_utf8_lossy(&bytes[..bytes.len().min(8)]))
        )),
    }
}

/// Checks the decoded size of a `width × height` image of `channels` samples of
/// `bytes_per_sample` bytes; returns the number of samples.
fn checked_samples(
    width: u32,
    height: u32,
    channels: usize,
    bytes_per_sample: usize,
) -> Result<usize, NavMapErrorKind> {
    let size_error = |reason: String| NavMapErrorKind::ImageSize {
        width: width.into(),
        height: height.into(),
        reason,
    };
    if width == 0 || height == 0 {
        return Err(size_error("empty".to_owned()));
    }
    let cells = u64::from(width) * u64::from(height);
    if cells > MAX_MAP_CELLS {
        return Err(size_error(format!(
            "too large ({cells} cells, at most {MAX_MAP_CELLS})"
        )));
    }
    let samples = cells * channels as u64;
    let bytes = samples * bytes_per_sample as u64;
    if bytes > MAX_IMAGE_BYTES {
        return Err(size_error(format!(
            "too large ({bytes} bytes decoded, at most {MAX_IMAGE_BYTES})"
        )));
    }
    usize::try_from(samples).map_err(|_| size_error("too large for this machine".to_owned()))
}

fn decode_png(bytes: &[u8]) -> Result<Raster, NavMapErrorKind> {
    let malformed = |e: png::DecodingError| NavMapErrorKind::MalformedImage {
        format: "PNG",
        reason: e.to_string(),
    };
    let mut decoder = png::Decoder::new_with_limits(
        bytes,
        png::Limits {
            bytes: MAX_IMAGE_BYTES as usize,
        },
    );
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(malformed)?;
    let (width, height) = (reader.info().width, reader.info().height);
    let (colour_type, depth) = reader.output_color_type();
    let channels = match colour_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => {
            return Err(NavMapErrorKind::MalformedImage {
                format: "PNG",
                reason: "the palette could not be expanded".to_owned(),
            });
        }
    };
    let bytes_per_sample = match depth {
        png::BitDepth::Eight => 1,
        png::BitDepth::Sixteen => 2,
        other => {
            return Err(NavMapErrorKind::MalformedImage {
                format: "PNG",
                reason: format!("unexpected bit depth {other:?} after expansion"),
            });
        }
    };
    let samples = checked_samples(width, height, channels, bytes_per_sample)?;
    let mut buffer = vec![0; samples * bytes_per_sample];
    let frame = reader.next_frame(&mut buffer).map_err(malformed)?;
    if frame.buffer_size() != buffer.len() {
        return Err(NavMapErrorKind::MalformedImage {
            format: "PNG",
            reason: format!(
                "decoded {} bytes where {} x {} pixels need {}",
                frame.buffer_size(),
                width,
                height,
                buffer.len()
            ),
        });
    }
    let (maxval, samples) = if bytes_per_sample == 1 {
        (255, Samples::Eight(buffer))
    } else {
        let wide = buffer
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect();
        (65535, Samples::Sixteen(wide))
    };
    Ok(Raster {
        width,
        height,
        channels,
        maxval,
        samples,
    })
}

/// Reads Netpbm `P2`, `P3`, `P5` and `P6` images.
fn decode_pnm(bytes: &[u8]) -> Result<Raster, NavMapErrorKind> {
    let (format, channels, binary) = match bytes[1] {
        b'2' => ("PGM", 1, false),
        b'5' => ("PGM", 1, true),
        b'3' => ("PPM", 3, false),
        _ => ("PPM", 3, true),
    };
    let malformed = |reason: String| NavMapErrorKind::MalformedImage { format, reason };
    let mut cursor = PnmCursor { bytes, pos: 2 };
    if !cursor.at_separator() {
        return Err(malformed(format!(
            "the magic number {:?} is not followed by whitespace",
            String::from_utf8_lossy(&bytes[..bytes.len().min(3)])
        )));
    }
    let width = cursor.header_number("width").map_err(&malformed)?;
    let height = cursor.header_number("height").map_err(&malformed)?;
    let maxval = cursor.header_number("maxval").map_err(&malformed)?;
    if !(1..=65535).contains(&maxval) {
        return Err(malformed(format!("maxval {maxval} is not in 1..=65535")));
    }
    let bytes_per_sample = if maxval < 256 { 1 } else { 2 };
    let count = checked_samples(width, height, channels, bytes_per_sample)?;
    let samples = if binary {
        // Exactly one whitespace byte separates the maxval from the raster.
        match bytes.get(cursor.pos) {
            Some(b) if b.is_ascii_whitespace() => cursor.pos += 1,
            Some(_) => {
                return Err(malformed(
                    "the maxval is not followed by a whitespace character".to_owned(),
                ));
            }
            None => {
                return Err(NavMapErrorKind::TruncatedImage {
                    expected: (count * bytes_per_sample) as u64,
                    actual: 0,
                    unit: "bytes",
                });
            }
        }
        let raster = &bytes[cursor.pos..];
        let expected = (count * bytes_per_sample) as u64;
        let actual = raster.len() as u64;
        if actual < expected {
            return Err(NavMapErrorKind::TruncatedImage {
                expected,
                actual,
                unit: "bytes",
            });
        }
        if actual > expected {
            return Err(NavMapErrorKind::TrailingData {
                expected,
                actual,
                unit: "bytes",
            });
        }
        if bytes_per_sample == 1 {
            Samples::Eight(raster.to_vec())
        } else {
            Samples::Sixteen(
                raster
                    .chunks_exact(2)
                    .map(|b| u16::from_be_bytes([b[0], b[1]]))
                    .collect(),
            )
        }
    } else {
        let mut values = Vec::with_capacity(count.min(bytes.len() / 2 + 1));
        while values.len() < count {
            match cursor.next_token() {
                Some(token) => values.push(
                    parse_decimal(token)
                        .filter(|&v| v <= 65535)
                        .ok_or_else(|| {
                            malformed(format!(
                                "sample {} is {:?}, not a number in 0..=65535",
                                values.len() + 1,
                                shorten(&String::from_utf8_lossy(token))
                            ))
                        })? as u16,
                ),
                None => {
                    return Err(NavMapErrorKind::TruncatedImage {
                        expected: count as u64,
                        actual: values.len() as u64,
                        unit: "samples",
                    });
                }
            }
        }
        let mut extra = 0;
        while cursor.next_token().is_some() {
            extra += 1;
        }
        if extra > 0 {
            return Err(NavMapErrorKind::TrailingData {
                expected: count as u64,
                actual: (count + extra) as u64,
                unit: "samples",
            });
        }
        Samples::Sixteen(values)
    };
    let raster = Raster {
        width,
        height,
        channels,
        maxval,
        samples,
    };
    if let Some(i) = (0..count).find(|&i| raster.sample(i) > maxval) {
        let pixel = i / channels;
        return Err(malformed(format!(
            "sample {} of pixel ({}, {}) (column, row from the top) exceeds the maxval {maxval}",
            raster.sample(i),
            pixel % width as usize,
            pixel / width as usize
        )));
    }
    Ok(raster)
}

/// Position in a Netpbm file.
struct PnmCursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> PnmCursor<'a> {
    /// Whether the next byte separates tokens (whitespace or a comment), or the file ends.
    fn at_separator(&self) -> bool {
        self.bytes
            .get(self.pos)
            .is_none_or(|&b| b.is_ascii_whitespace() || b == b'#')
    }

    /// Skips whitespace and `#` comments (to the end of their line).
    fn skip_separators(&mut self) {
        while let Some(&b) = self.bytes.get(self.pos) {
            if b.is_ascii_whitespace() {
                self.pos += 1;
            } else if b == b'#' {
                while let Some(&c) = self.bytes.get(self.pos) {
                    if c == b'\n' || c == b'\r' {
                        break;
                    }
                    self.pos += 1;
                }
            } else {
                break;
            }
        }
    }

    /// The next run of bytes up to a separator, after skipping separators.
    fn next_token(&mut self) -> Option<&'a [u8]> {
        self.skip_separators();
        let start = self.pos;
        while !self.at_separator() {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.bytes[start..self.pos])
    }

    fn header_number(&mut self, what: &str) -> Result<u32, String> {
        let token = self
            .next_token()
            .ok_or_else(|| format!("the header ends before the {what}"))?;
        let text = shorten(&String::from_utf8_lossy(token));
        if token.iter().all(u8::is_ascii_digit) {
            return parse_decimal(token)
                .and_then(|v| u32::try_from(v).ok())
                .ok_or_else(|| format!("{what}: {text} is too large"));
        }
        Err(format!(
            "{what}: {text:?} is not a number (expected a header \
             \"P5 <width> <height> <maxval>\")"
        ))
    }
}

/// An unsigned decimal number of ASCII digits only.
fn parse_decimal(token: &[u8]) -> Option<u64> {
    if token.is_empty() || token.len() > 19 || !token.iter().all(u8::is_ascii_digit) {
        return None;
    }
    std::str::from_utf8(token).ok()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graphicsmagick_levels_match_its_output() {
        // Bytes written by GraphicsMagick 1.3.40 (Q16) for ColorGray(205/255), (254/255), 0, 0.5.
        assert_eq!(graphicsmagick_grey(205.0 / 255.0), 205);
        assert_eq!(graphicsmagick_grey(254.0 / 255.0), 254);
        assert_eq!(graphicsmagick_grey(0.0), 0);
        assert_eq!(graphicsmagick_grey(0.5), 127);
        // Raw mode: v / 255 · MaxRGB gives back v for every cell value.
        for v in 0..=100u8 {
            assert_eq!(graphicsmagick_grey(f64::from(v) / 255.0), v);
        }
        // Scale mode truncates: observed 249 for v = 2 and 127 for v = 50.
        assert_eq!(graphicsmagick_grey((100.0 - 2.0) / 100.0), 249);
        assert_eq!(graphicsmagick_grey((100.0 - 50.0) / 100.0), 127);
    }

    #[test]
    fn yaml_strings_are_plain_only_when_safe() {
        assert_eq!(yaml_string("map.pgm"), "map.pgm");
        assert_eq!(yaml_string("my map (v2).pgm"), "my map (v2).pgm");
        assert_eq!(yaml_string("map: v2.pgm"), "\"map: v2.pgm\"");
        assert_eq!(yaml_string("#map.pgm"), "\"#map.pgm\"");
        assert_eq!(yaml_string("- map.pgm"), "\"- map.pgm\"");
        assert_eq!(yaml_string("a\"b\\c\n.pgm"), "\"a\\\"b\\\\c\\n.pgm\"");
        assert_eq!(yaml_string("true"), "\"true\"");
        assert_eq!(yaml_string("1.5"), "\"1.5\"");
        assert_eq!(yaml_string("bell\u{7}.pgm"), "\"bell\\u0007.pgm\"");
    }
}
