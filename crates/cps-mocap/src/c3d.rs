//! C3D, read and written by cps's own code: the header block, the parameter section
//! (groups and parameters, every size checked against the bytes that hold it) and the
//! 3-D point and analog data, in integer or floating-point form, for Intel, DEC and MIPS
//! files.
//!
//! Layout (the C3D manual, <https://www.c3d.org>): 512-byte blocks. Block 1 is the header
//! (16-bit words: the parameter block, points per frame, analog values per frame, first
//! and last frame, the scale factor, the data block, the frame rate). The parameter
//! section starts with four bytes (the last is the processor: 84 Intel, 85 DEC, 86 MIPS)
//! and holds records chained by 16-bit offsets. The data are frames of `4 × points`
//! values (X, Y, Z and a residual word; 16-bit integers times `POINT:SCALE`, or 32-bit
//! floats when the scale is negative) followed by the frame's analog samples.
//!
//! The parameters win over the header where both say something (as ezc3d reads them). A
//! take longer than 65 535 frames cannot state its length in the header: it is taken from
//! `TRIAL:ACTUAL_END_FIELD` or `POINT:LONG_FRAMES`, or else from the file's length (the
//! block padding after the last frame left out), and said so in [`Take::notes`].

use std::collections::HashMap;
use std::path::Path;

use crate::error::MocapError;
use crate::take::{Analog, Processor, Source, Take, metres_per_unit};

/// A parameter's value as stored.
#[derive(Debug, Clone, PartialEq)]
enum Data {
    Chars(Vec<u8>),
    Bytes(Vec<u8>),
    Ints(Vec<i16>),
    Floats(Vec<f32>),
}

#[derive(Debug, Clone)]
struct Param {
    dims: Vec<usize>,
    data: Data,
}

impl Param {
    fn floats(&self) -> Vec<f64> {
        match &self.data {
            Data::Floats(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Data::Ints(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Data::Bytes(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Data::Chars(_) => Vec::new(),
        }
    }

    /// 16-bit counts are unsigned in practice (a `POINT:USED` of 40 000 is stored as a
    /// negative `i16`).
    fn count(&self) -> Option<u64> {
        match &self.data {
            Data::Ints(v) => v.first().map(|&x| u64::from(x as u16)),
            Data::Bytes(v) => v.first().map(|&x| u64::from(x)),
            Data::Floats(v) => v
                .first()
                .filter(|x| x.is_finite() && **x >= 0.0)
                .map(|&x| x as u64),
            Data::Chars(_) => None,
        }
    }

    /// A character array as strings: the first dimension is the length of each.
    fn strings(&self) -> Vec<String> {
        let Data::Chars(bytes) = &self.data else {
            return Vec::new();
        };
        let width = self.dims.first().copied().unwrap_or(bytes.len()).max(1);
        if self.dims.len() <= 1 {
            return vec![text(bytes)];
        }
        bytes.chunks(width).map(text).collect()
    }
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes)
        .trim_end_matches(['\0', ' '])
        .trim_start()
        .to_string()
}

/// Reads numbers in a file's processor convention.
#[derive(Debug, Clone, Copy)]
struct Endian(Processor);

impl Endian {
    fn u16(self, b: [u8; 2]) -> u16 {
        match self.0 {
            Processor::Mips => u16::from_be_bytes(b),
            _ => u16::from_le_bytes(b),
        }
    }
    fn i16(self, b: [u8; 2]) -> i16 {
        self.u16(b) as i16
    }
    fn f32(self, b: [u8; 4]) -> f32 {
        match self.0 {
            Processor::Intel => f32::from_le_bytes(b),
            Processor::Mips => f32::from_be_bytes(b),
            // A VAX F float: its two 16-bit words swapped give IEEE's bits, four times
            // the value (exponent bias 128, hidden bit at 0.1).
            Processor::Dec => {
                let v = f32::from_le_bytes([b[2], b[3], b[0], b[1]]);
                v / 4.0
            }
        }
    }
    fn put_u16(self, v: u16) -> [u8; 2] {
        match self.0 {
            Processor::Mips => v.to_be_bytes(),
            _ => v.to_le_bytes(),
        }
    }
    fn put_f32(self, v: f32) -> [u8; 4] {
        match self.0 {
            Processor::Intel => v.to_le_bytes(),
            Processor::Mips => v.to_be_bytes(),
            Processor::Dec => {
                let b = (v * 4.0).to_le_bytes();
                [b[2], b[3], b[0], b[1]]
            }
        }
    }
}

/// A bounded view of the file: every read names its offset when it runs past the end.
struct Bytes<'a> {
    b: &'a [u8],
    file: &'a str,
}

impl<'a> Bytes<'a> {
    fn get(&self, at: usize, n: usize, what: &str) -> Result<&'a [u8], MocapError> {
        at.checked_add(n)
            .and_then(|end| self.b.get(at..end))
            .ok_or_else(|| {
                MocapError::format(
                    self.file,
                    format!(
                        "truncated: {what} needs bytes {at}..{} but the file has {} bytes",
                        at.saturating_add(n),
                        self.b.len()
                    ),
                )
            })
    }
    fn two(&self, at: usize, what: &str) -> Result<[u8; 2], MocapError> {
        let s = self.get(at, 2, what)?;
        Ok([s[0], s[1]])
    }
}

/// Reads a C3D file.
pub fn read(path: &Path) -> Result<Take, MocapError> {
    let (bytes, name) = crate::take::read_file(path)?;
    parse(&bytes, &name)
}

/// Parses the bytes of a C3D file (`file` names it in messages).
// Long on purpose (over 150 lines): it reads the file in the order of its layout (header,
// parameter section, data), each check beside the bytes it guards.
pub fn parse(bytes: &[u8], file: &str) -> Result<Take, MocapError> {
    let b = Bytes { b: bytes, file };
    let bad = |m: String| MocapError::format(file, m);
    let head = b.get(0, 512, "the header block")?;
    if head[1] != 0x50 {
        return Err(bad(format!(
            "not a C3D file: byte 2 is 0x{:02x}, a C3D header has 0x50 there",
            head[1]
        )));
    }
    if head[0] == 0 {
        return Err(bad(
            "byte 1 (the parameter section's block) is 0; blocks count from 1".into(),
        ));
    }
    let param_start = (usize::from(head[0]) - 1) * 512;
    let pblock = b.get(param_start, 4, "the parameter section's first bytes")?;
    let processor = match pblock[3] {
        84 => Processor::Intel,
        85 => Processor::Dec,
        86 => Processor::Mips,
        p => {
            return Err(bad(format!(
                "byte {} (the processor type) is {p}; C3D knows 84 (Intel), 85 (DEC) and 86 (MIPS)",
                param_start + 4
            )));
        }
    };
    let e = Endian(processor);
    let word = |i: usize| e.u16([head[2 * i - 2], head[2 * i - 1]]);
    let h_points = usize::from(word(2));
    let h_analog_per_frame = usize::from(word(3));
    let h_first = u64::from(word(4));
    let h_last = u64::from(word(5));
    let h_scale = e.f32([head[12], head[13], head[14], head[15]]);
    let h_data_block = usize::from(word(9));
    let h_rate = e.f32([head[20], head[21], head[22], head[23]]);

    let params = parameters(&b, e, param_start, h_data_block)?;
    let p = |g: &str, n: &str| params.get(&(g.to_string(), n.to_string()));

    let points = p("POINT", "USED")
        .and_then(Param::count)
        .map_or(h_points, |v| v as usize);
    let scale = p("POINT", "SCALE")
        .and_then(|s| s.floats().first().copied())
        .map_or(h_scale, |v| v as f32);
    let scale = if scale == 0.0 { h_scale } else { scale };
    let float = scale < 0.0 || (scale == 0.0 && h_scale < 0.0);
    let scale_abs = scale.abs();
    if !scale_abs.is_finite() {
        return Err(bad(format!("the point scale factor is {scale}")));
    }
    let rate = p("POINT", "RATE")
        .and_then(|s| s.floats().first().copied())
        .filter(|r| *r > 0.0)
        .unwrap_or(f64::from(h_rate));
    if !(rate.is_finite() && rate > 0.0) && points > 0 {
        return Err(bad(format!(
            "the frame rate is {rate} (header and POINT:RATE); it must be a positive number"
        )));
    }
    let data_block = p("POINT", "DATA_START")
        .and_then(Param::count)
        .map_or(h_data_block, |v| v as usize);
    if data_block < 2 || (data_block - 1) * 512 <= param_start {
        return Err(bad(format!(
            "the data section is said to start at block {data_block}, before the end of the parameter section (block {})",
            param_start / 512 + 1
        )));
    }
    let data_start = (data_block - 1) * 512;

    // Labels: POINT:LABELS, then LABELS2, LABELS3… for takes of more than 255 markers.
    let mut labels: Vec<String> = Vec::new();
    for name in std::iter::once("LABELS".to_string()).chain((2..100).map(|i| format!("LABELS{i}")))
    {
        match p("POINT", &name) {
            Some(l) => labels.extend(l.strings()),
            None if name != "LABELS" => break,
            None => {}
        }
    }
    labels.truncate(points);
    while labels.len() < points {
        labels.push(format!("point{}", labels.len() + 1));
    }
    let units = p("POINT", "UNITS")
        .and_then(|u| u.strings().into_iter().next())
        .unwrap_or_default();
    let metres = if units.is_empty() {
        0.001
    } else {
        metres_per_unit(&units).ok_or_else(|| {
            bad(format!(
                "POINT:UNITS is \"{units}\"; cps reads m, cm and mm"
            ))
        })?
    };

    // Analog channels.
    let channels = p("ANALOG", "USED").and_then(Param::count).unwrap_or(0) as usize;
    let analog_per_frame = h_analog_per_frame;
    let samples_per_frame = if channels == 0 {
        0
    } else if analog_per_frame % channels != 0 {
        return Err(bad(format!(
            "the header's {analog_per_frame} analog values per frame are not a multiple of ANALOG:USED ({channels} channels)"
        )));
    } else {
        analog_per_frame / channels
    };
    let analog_values = if channels == 0 { 0 } else { analog_per_frame };

    let value_bytes = if float { 4 } else { 2 };
    let frame_bytes = (4 * points + analog_values) * value_bytes;
    let mut notes = Vec::new();
    let available = bytes.len().saturating_sub(data_start);
    let whole = available.checked_div(frame_bytes).unwrap_or(0);

    // The frame count: the header, unless a parameter says more.
    let header_frames = if h_last >= h_first && h_last > 0 {
        (h_last - h_first + 1) as usize
    } else {
        0
    };
    let first_frame = h_first.max(1);
    let mut frames = p("POINT", "FRAMES")
        .and_then(Param::count)
        .map_or(header_frames, |v| v as usize);
    let long = frames >= 65_535 || h_last == 65_535;
    if long {
        let end = p("TRIAL", "ACTUAL_END_FIELD").and_then(field);
        let start = p("TRIAL", "ACTUAL_START_FIELD").and_then(field);
        if let (Some(s), Some(t)) = (start, end)
            && t >= s
        {
            frames = (t - s + 1) as usize;
        } else if let Some(n) = p("POINT", "LONG_FRAMES").and_then(Param::count) {
            frames = n as usize;
        } else if frame_bytes > 0 {
            // Count the frames the file holds, leaving out the block padding at its end.
            let mut n = whole;
            while n > 0 {
                let at = data_start + (n - 1) * frame_bytes;
                if bytes[at..at + frame_bytes].iter().any(|&x| x != 0) {
                    break;
                }
                n -= 1;
            }
            if n > frames {
                notes.push(format!(
                    "{n} frames, counted from the file's length (the header holds at most 65 535 and no parameter gives the count)"
                ));
                frames = n;
            }
        }
    }
    if frame_bytes == 0 {
        // No points and no analog values: nothing to read, whatever the count says.
        frames = 0;
    }
    if frame_bytes > 0 && frames > whole {
        return Err(bad(format!(
            "truncated: {frames} frames of {frame_bytes} bytes are declared from byte {data_start}, but the file ends at byte {} ({whole} whole frames)",
            bytes.len()
        )));
    }
    if points > 0 && !(rate.is_finite() && rate > 0.0) {
        return Err(bad("no frame rate (header and POINT:RATE are 0)".into()));
    }

    // Analog scaling: (raw − offset) · scale[c] · GEN_SCALE.
    let analog = if channels > 0 {
        let gen_scale = p("ANALOG", "GEN_SCALE")
            .and_then(|s| s.floats().first().copied())
            .unwrap_or(1.0);
        let scales = p("ANALOG", "SCALE").map(Param::floats).unwrap_or_default();
        let offsets = p("ANALOG", "OFFSET").map(Param::floats).unwrap_or_default();
        let unsigned = p("ANALOG", "FORMAT")
            .and_then(|f| f.strings().into_iter().next())
            .is_some_and(|f| f.eq_ignore_ascii_case("UNSIGNED"));
        let mut alabels = p("ANALOG", "LABELS")
            .map(Param::strings)
            .unwrap_or_default();
        alabels.resize(channels, String::new());
        for (i, l) in alabels.iter_mut().enumerate() {
            if l.is_empty() {
                *l = format!("channel{}", i + 1);
            }
        }
        let mut aunits = p("ANALOG", "UNITS").map(Param::strings).unwrap_or_default();
        aunits.resize(channels, String::new());
        let arate = p("ANALOG", "RATE")
            .and_then(|s| s.floats().first().copied())
            .unwrap_or(rate * samples_per_frame as f64);
        Some((
            Analog {
                labels: alabels,
                units: aunits,
                rate: arate,
                samples_per_frame,
                values: Vec::with_capacity(frames * analog_per_frame),
            },
            (0..channels)
                .map(|c| {
                    (
                        offsets.get(c).copied().unwrap_or(0.0),
                        scales.get(c).copied().unwrap_or(1.0) * gen_scale,
                    )
                })
                .collect::<Vec<_>>(),
            unsigned,
        ))
    } else {
        None
    };

    let mut xyz = Vec::with_capacity(frames * points);
    let mut residual = Vec::with_capacity(frames * points);
    let mut analog = analog;
    // `frames ≤ whole` above: the data lie within the file.
    let data = bytes
        .get(data_start..data_start + frames * frame_bytes)
        .unwrap_or_default();
    for frame in data.chunks_exact(frame_bytes.max(1)).take(frames) {
        let (pts, ana) = frame.split_at(4 * points * value_bytes);
        if float {
            for q in pts.chunks_exact(16) {
                let x = e.f32([q[0], q[1], q[2], q[3]]);
                let y = e.f32([q[4], q[5], q[6], q[7]]);
                let z = e.f32([q[8], q[9], q[10], q[11]]);
                // The fourth value as two 16-bit words (as ezc3d reads it): Intel and
                // MIPS put the camera mask first, DEC the residual first.
                let r = match processor {
                    Processor::Dec => e.i16([q[12], q[13]]),
                    _ => e.i16([q[14], q[15]]),
                };
                push_point(&mut xyz, &mut residual, [x, y, z], r, scale_abs, true);
            }
        } else {
            for q in pts.chunks_exact(8) {
                let v = |i: usize| f32::from(e.i16([q[i], q[i + 1]])) * scale_abs;
                let word = e.i16([q[6], q[7]]);
                push_point(
                    &mut xyz,
                    &mut residual,
                    [v(0), v(2), v(4)],
                    word,
                    scale_abs,
                    false,
                );
            }
        }
        if let Some((a, scale, unsigned)) = analog.as_mut() {
            for (k, s) in ana.chunks_exact(value_bytes).enumerate() {
                let raw = if float {
                    f64::from(e.f32([s[0], s[1], s[2], s[3]]))
                } else if *unsigned {
                    f64::from(e.u16([s[0], s[1]]))
                } else {
                    f64::from(e.i16([s[0], s[1]]))
                };
                let (offset, gain) = scale[k % channels];
                a.values.push((raw - offset) * gain);
            }
        }
    }
    Ok(Take {
        file: file.to_string(),
        source: Source::C3d { float, processor },
        labels,
        rate,
        first_frame,
        frames,
        units: if units.is_empty() { "mm".into() } else { units },
        metres_per_unit: metres,
        xyz,
        residual,
        analog: analog.map(|(a, _, _)| a),
        rigid_bodies: Vec::new(),
        notes,
    })
}

/// One point: missing when its residual word is negative (or a coordinate is not
/// finite); the residual is the word's residual part times the scale.
fn push_point(
    xyz: &mut Vec<[f32; 3]>,
    residual: &mut Vec<f32>,
    p: [f32; 3],
    word: i16,
    scale: f32,
    float: bool,
) {
    if word < 0 || p.iter().any(|v| !v.is_finite()) {
        xyz.push([f32::NAN; 3]);
        residual.push(-1.0);
    } else {
        let r = if float {
            f32::from(word) * scale
        } else {
            f32::from((word >> 8) as u8) * scale
        };
        xyz.push(p);
        residual.push(r);
    }
}

/// `TRIAL:ACTUAL_*_FIELD`: two 16-bit words, low first.
fn field(p: &Param) -> Option<u64> {
    match &p.data {
        Data::Ints(v) if v.len() == 2 => {
            Some(u64::from(v[0] as u16) + (u64::from(v[1] as u16) << 16))
        }
        _ => None,
    }
}

type Params = HashMap<(String, String), Param>;

/// The parameter section: group records (negative id) name the groups, parameter records
/// (positive id) hold typed arrays. Each record's size is checked against its chain offset
/// and the section's end.
fn parameters(
    b: &Bytes<'_>,
    e: Endian,
    start: usize,
    data_block: usize,
) -> Result<Params, MocapError> {
    let bad = |m: String| MocapError::format(b.file, m);
    // The section ends where the data begin (the header's data block), or at the file's
    // end for files whose header says 0.
    let end = if data_block > 1 {
        ((data_block - 1) * 512).min(b.b.len())
    } else {
        b.b.len()
    };
    let mut groups: HashMap<i8, String> = HashMap::new();
    let mut pending: Vec<(i8, String, Param)> = Vec::new();
    let mut at = start + 4;
    let mut records = 0usize;
    loop {
        if at + 2 > end {
            break;
        }
        records += 1;
        if records > 100_000 {
            return Err(bad(format!(
                "the parameter section at byte {start} chains more than 100 000 records"
            )));
        }
        let head = b.get(at, 2, "a parameter record")?;
        let n = (head[0] as i8).unsigned_abs() as usize;
        let id = head[1] as i8;
        if n == 0 || id == 0 {
            break;
        }
        let name_bytes = b.get(at + 2, n, "a parameter name")?;
        let name = String::from_utf8_lossy(name_bytes)
            .trim()
            .to_ascii_uppercase();
        let off_at = at + 2 + n;
        let offset = e.i16(b.two(off_at, &format!("the offset of record {name}"))?);
        let next = if offset == 0 {
            None
        } else if offset < 0 {
            return Err(bad(format!(
                "parameter record {name} at byte {at} points back ({offset} bytes) instead of to the next record"
            )));
        } else {
            Some(off_at + offset as usize)
        };
        let record_end = next.unwrap_or(end).min(end);
        let mut p = off_at + 2;
        if id > 0 {
            let kind = b.get(p, 2, &format!("the type of parameter {name}"))?;
            let (ty, ndims) = (kind[0] as i8, usize::from(kind[1]));
            let dims: Vec<usize> = b
                .get(p + 2, ndims, &format!("the dimensions of parameter {name}"))?
                .iter()
                .map(|&d| usize::from(d))
                .collect();
            p += 2 + ndims;
            let count = if ndims == 0 {
                1
            } else {
                dims.iter()
                    .try_fold(1usize, |a, &d| a.checked_mul(d))
                    .unwrap_or(usize::MAX / 8)
            };
            let size = match ty {
                -1 | 1 => 1,
                2 => 2,
                4 => 4,
                t => {
                    return Err(bad(format!(
                        "parameter {name} at byte {at} has type {t}; C3D knows -1 (characters), 1 (bytes), 2 (integers) and 4 (floats)"
                    )));
                }
            };
            let nbytes = count.saturating_mul(size);
            if p.saturating_add(nbytes) > record_end {
                return Err(bad(format!(
                    "parameter {name} at byte {at} declares {count} values of {size} byte(s) (dimensions {dims:?}), {nbytes} bytes, but its record ends at byte {record_end}"
                )));
            }
            let raw = b.get(p, nbytes, &format!("the values of parameter {name}"))?;
            let data = match ty {
                -1 => Data::Chars(raw.to_vec()),
                1 => Data::Bytes(raw.to_vec()),
                2 => Data::Ints(raw.chunks_exact(2).map(|c| e.i16([c[0], c[1]])).collect()),
                _ => Data::Floats(
                    raw.chunks_exact(4)
                        .map(|c| e.f32([c[0], c[1], c[2], c[3]]))
                        .collect(),
                ),
            };
            pending.push((id, name, Param { dims, data }));
        } else {
            groups.insert(id.wrapping_neg(), name);
        }
        match next {
            Some(n) if n > at => at = n,
            _ => break,
        }
    }
    let mut out = HashMap::new();
    for (id, name, param) in pending {
        let group = groups
            .get(&id)
            .cloned()
            .unwrap_or_else(|| format!("GROUP{id}"));
        out.insert((group, name), param);
    }
    Ok(out)
}

/// How [`write()`] stores the points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Format {
    /// 32-bit floats (`POINT:SCALE` negative: its magnitude scales only the residuals).
    Float,
    /// 16-bit integers times `scale` (file units per count).
    Integer {
        /// File units per integer count.
        scale: f32,
    },
}

/// Writes `take`'s markers (and analog channels) as a C3D file on an Intel processor,
/// for tests, examples and benchmarks. Missing samples are written as Vicon and Qualisys
/// do (zeros, residual −1). A take of more than 65 535 frames states its length in
/// `TRIAL:ACTUAL_START_FIELD`/`ACTUAL_END_FIELD` (the header holds 65 535).
pub fn write(take: &Take, format: Format) -> Result<Vec<u8>, MocapError> {
    let e = Endian(Processor::Intel);
    let points = take.markers();
    let (float, scale) = match format {
        Format::Float => (true, -1.0f32),
        Format::Integer { scale } => (false, scale),
    };
    if !(float || scale > 0.0 && scale.is_finite()) {
        return Err(MocapError::Input(format!(
            "an integer C3D needs a positive scale (got {scale})"
        )));
    }
    if points > 32_767 {
        return Err(MocapError::Input(format!(
            "{points} markers: a C3D file holds at most 32 767"
        )));
    }
    let analog = take.analog.as_ref().filter(|a| a.channels() > 0);
    let channels = analog.map_or(0, Analog::channels);
    let spf = analog.map_or(0, |a| a.samples_per_frame);
    // Parameters.
    let mut ps = ParamWriter::new(e);
    ps.group(1, "POINT");
    ps.group(2, "ANALOG");
    ps.group(3, "TRIAL");
    ps.ints(1, "USED", &[points as u16 as i16]);
    ps.floats(1, "SCALE", &[scale]);
    ps.floats(1, "RATE", &[take.rate as f32]);
    let frames_word = if take.frames > 65_535 {
        -1
    } else {
        take.frames as u16 as i16
    };
    ps.ints(1, "FRAMES", &[frames_word]);
    for (k, chunk) in take.labels.chunks(255).enumerate() {
        let name = if k == 0 {
            "LABELS".to_string()
        } else {
            format!("LABELS{}", k + 1)
        };
        ps.chars(1, &name, chunk, 32);
    }
    ps.chars(1, "UNITS", std::slice::from_ref(&take.units), 4);
    let data_start_at = ps.ints(1, "DATA_START", &[0]);
    ps.ints(2, "USED", &[channels as i16]);
    if let Some(a) = analog {
        ps.floats(2, "RATE", &[a.rate as f32]);
        ps.floats(2, "GEN_SCALE", &[1.0]);
        ps.floats(2, "SCALE", &vec![1.0; channels]);
        ps.ints(2, "OFFSET", &vec![0; channels]);
        ps.chars(2, "LABELS", &a.labels, 16);
        ps.chars(2, "UNITS", &a.units, 4);
    }
    let last = take.first_frame + take.frames as u64 - 1;
    ps.ints(
        3,
        "ACTUAL_START_FIELD",
        &[
            take.first_frame as u16 as i16,
            (take.first_frame >> 16) as u16 as i16,
        ],
    );
    ps.ints(
        3,
        "ACTUAL_END_FIELD",
        &[last as u16 as i16, (last >> 16) as u16 as i16],
    );
    let mut params = ps.finish();
    let param_blocks = params.len().div_ceil(512);
    params.resize(param_blocks * 512, 0);
    params[2] = param_blocks as u8;
    let data_block = 2 + param_blocks;
    let db = e.put_u16(data_block as u16);
    params[data_start_at..data_start_at + 2].copy_from_slice(&db);

    let mut out = vec![0u8; 512];
    out[0] = 2;
    out[1] = 0x50;
    let mut put = |i: usize, v: u16| out[2 * i - 2..2 * i].copy_from_slice(&e.put_u16(v));
    put(2, points as u16);
    put(3, (channels * spf) as u16);
    put(4, take.first_frame.min(65_535) as u16);
    put(5, last.min(65_535) as u16);
    put(6, 10);
    put(9, data_block as u16);
    put(10, spf as u16);
    out[12..16].copy_from_slice(&e.put_f32(scale));
    out[20..24].copy_from_slice(&e.put_f32(take.rate as f32));
    out.extend_from_slice(&params);

    let value_bytes = if float { 4 } else { 2 };
    out.reserve(take.frames * (4 * points + channels * spf) * value_bytes);
    for f in 0..take.frames {
        for m in 0..points {
            let i = f * points + m;
            let p = take.xyz[i];
            let seen = take.residual[i] >= 0.0 && p.iter().all(|v| v.is_finite());
            if float {
                if seen {
                    for v in p {
                        out.extend_from_slice(&e.put_f32(v));
                    }
                    let r = (take.residual[i] / scale.abs())
                        .round()
                        .clamp(0.0, 32_767.0) as u16;
                    out.extend_from_slice(&[0, 0]);
                    out.extend_from_slice(&e.put_u16(r));
                } else {
                    out.extend_from_slice(&[0; 12]);
                    out.extend_from_slice(&e.put_f32(-1.0));
                }
            } else if seen {
                for v in p {
                    let c = (v / scale).round();
                    if !(-32_768.0..=32_767.0).contains(&c) {
                        return Err(MocapError::Input(format!(
                            "marker {} at frame {f} is {v} {}, beyond what 16-bit integers times {scale} hold",
                            take.labels[m], take.units
                        )));
                    }
                    out.extend_from_slice(&e.put_u16(c as i16 as u16));
                }
                let r = (take.residual[i] / scale).round().clamp(0.0, 127.0) as u16;
                out.extend_from_slice(&e.put_u16(r << 8));
            } else {
                out.extend_from_slice(&[0; 6]);
                out.extend_from_slice(&e.put_u16(0xff00));
            }
        }
        if let Some(a) = analog {
            for s in 0..spf {
                for c in 0..channels {
                    let v = a.values[(f * spf + s) * channels + c];
                    if float {
                        out.extend_from_slice(&e.put_f32(v as f32));
                    } else {
                        out.extend_from_slice(
                            &e.put_u16(v.round().clamp(-32_768.0, 32_767.0) as i16 as u16),
                        );
                    }
                }
            }
        }
    }
    let padded = out.len().div_ceil(512) * 512;
    out.resize(padded, 0);
    Ok(out)
}

/// Builds a parameter section: four bytes, then records chained by offsets.
struct ParamWriter {
    e: Endian,
    out: Vec<u8>,
    last_offset_at: Option<usize>,
}

impl ParamWriter {
    fn new(e: Endian) -> Self {
        Self {
            e,
            out: vec![1, 0x50, 0, 84],
            last_offset_at: None,
        }
    }

    /// Starts a record; returns where its offset word is.
    fn record(&mut self, id: i8, name: &str) -> usize {
        let at = self.out.len();
        if let Some(prev) = self.last_offset_at {
            let off = (at - prev) as u16;
            let b = self.e.put_u16(off);
            self.out[prev..prev + 2].copy_from_slice(&b);
        }
        self.out.push(name.len() as u8);
        self.out.push(id as u8);
        self.out.extend_from_slice(name.as_bytes());
        let off_at = self.out.len();
        self.out.extend_from_slice(&[0, 0]);
        self.last_offset_at = Some(off_at);
        off_at
    }

    fn group(&mut self, id: i8, name: &str) {
        self.record(-id, name);
        self.out.push(0);
    }

    fn param(&mut self, id: i8, name: &str, ty: i8, dims: &[usize], data: &[u8]) -> usize {
        self.record(id, name);
        self.out.push(ty as u8);
        self.out.push(dims.len() as u8);
        self.out.extend(dims.iter().map(|&d| d as u8));
        let at = self.out.len();
        self.out.extend_from_slice(data);
        self.out.push(0);
        at
    }

    fn ints(&mut self, id: i8, name: &str, v: &[i16]) -> usize {
        let data: Vec<u8> = v.iter().flat_map(|&x| self.e.put_u16(x as u16)).collect();
        let dims = if v.len() == 1 { vec![] } else { vec![v.len()] };
        self.param(id, name, 2, &dims, &data)
    }

    fn floats(&mut self, id: i8, name: &str, v: &[f32]) -> usize {
        let data: Vec<u8> = v.iter().flat_map(|&x| self.e.put_f32(x)).collect();
        let dims = if v.len() == 1 { vec![] } else { vec![v.len()] };
        self.param(id, name, 4, &dims, &data)
    }

    fn chars(&mut self, id: i8, name: &str, v: &[String], width: usize) -> usize {
        let width = v
            .iter()
            .map(String::len)
            .max()
            .unwrap_or(0)
            .clamp(1, 255)
            .max(width.min(255));
        let mut data = Vec::with_capacity(width * v.len());
        for s in v {
            let mut b = s.as_bytes().to_vec();
            b.resize(width, b' ');
            data.extend(b);
        }
        self.param(id, name, -1, &[width, v.len()], &data)
    }

    fn finish(mut self) -> Vec<u8> {
        // The last record's offset stays 0: the chain ends there.
        self.out.extend_from_slice(&[0, 0]);
        self.out
    }
}
