//! CDR, the bytes of a ROS 2 message on the wire (OMG's Common Data Representation, XCDR
//! version 1, as every rmw writes it): a 4-byte encapsulation header (`00 01 00 00`
//! little-endian, `00 00 00 00` big-endian), then the fields in order, each primitive
//! aligned to its own size counted from the first byte after the header; a string is a
//! `uint32` length including its NUL, the bytes and the NUL; a sequence is a `uint32`
//! count and its items.
//!
//! [`CdrReader`] trusts nothing it reads: every length is checked against the bytes that
//! are left before anything is allocated, so a sample that lies about a size costs at most
//! its own length, and the error names the field and the byte offset.

use std::fmt;

/// A CDR message being written (little-endian, with its encapsulation header).
#[derive(Debug, Clone)]
pub struct CdrWriter {
    bytes: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty little-endian message (the encapsulation header only).
    pub fn new() -> Self {
        CdrWriter {
            bytes: vec![0, 1, 0, 0],
        }
    }

    fn align(&mut self, size: usize) {
        while !(self.bytes.len() - 4).is_multiple_of(size) {
            self.bytes.push(0);
        }
    }

    /// A `uint8` (or `bool`, `int8`, `byte`).
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.bytes.push(v);
        self
    }

    /// A `uint16`.
    pub fn u16(&mut self, v: u16) -> &mut Self {
        self.align(2);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `uint64`.
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.align(8);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `float32`.
    pub fn f32(&mut self, v: f32) -> &mut Self {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Raw bytes with no alignment (a fixed-size `uint8[N]` array).
    pub fn raw(&mut self, v: &[u8]) -> &mut Self {
        self.bytes.extend_from_slice(v);
        self
    }

    /// A `uint8[]` sequence.
    pub fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.u32(len32(v.len())).raw(v)
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(len32(s.len() + 1));
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(0);
        self
    }

    /// A `string[]`.
    pub fn strings(&mut self, v: &[String]) -> &mut Self {
        self.u32(len32(v.len()));
        for s in v {
            self.string(s);
        }
        self
    }

    /// A `float64[]`.
    pub fn f64s(&mut self, v: &[f64]) -> &mut Self {
        self.u32(len32(v.len()));
        for x in v {
            self.f64(*x);
        }
        self
    }

    /// A `builtin_interfaces/Time` or `Duration` of `ns` nanoseconds.
    pub fn time(&mut self, ns: u64) -> &mut Self {
        self.i32((ns / 1_000_000_000) as i32)
            .u32((ns % 1_000_000_000) as u32)
    }

    /// A `std_msgs/Header`.
    pub fn header(&mut self, stamp_ns: u64, frame_id: &str) -> &mut Self {
        self.time(stamp_ns).string(frame_id)
    }

    /// The finished bytes, encapsulation header included (what MCAP stores); DDS takes
    /// them without their first four bytes (its own header says the encoding).
    pub fn finish(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.bytes)
    }
}

/// A length as CDR's `uint32`; a message of 4 GiB or more is no message.
fn len32(n: usize) -> u32 {
    u32::try_from(n).expect("a CDR sequence or string shorter than 4 GiB")
}

/// Why a CDR sample could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CdrError {
    /// The field being read.
    pub field: &'static str,
    /// Its byte offset in the sample (after the encapsulation header).
    pub offset: usize,
    /// What was wrong.
    pub problem: String,
}

impl fmt::Display for CdrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "field `{}` at byte {}: {}",
            self.field, self.offset, self.problem
        )
    }
}

impl std::error::Error for CdrError {}

/// Reads a CDR sample's body (after the encapsulation header), either byte order.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    body: &'a [u8],
    at: usize,
    little: bool,
}

macro_rules! read_number {
    ($name:ident, $t:ty, $doc:literal) => {
        #[doc = $doc]
        pub fn $name(&mut self, field: &'static str) -> Result<$t, CdrError> {
            const N: usize = std::mem::size_of::<$t>();
            let b: [u8; N] = self.take(field, N, N)?.try_into().expect("N bytes");
            Ok(if self.little {
                <$t>::from_le_bytes(b)
            } else {
                <$t>::from_be_bytes(b)
            })
        }
    };
}

impl<'a> CdrReader<'a> {
    /// A reader of `body` (the sample without its encapsulation header), little-endian
    /// or not.
    pub fn new(body: &'a [u8], little_endian: bool) -> Self {
        CdrReader {
            body,
            at: 0,
            little: little_endian,
        }
    }

    /// A reader of a whole sample, encapsulation header first (`00 01` little-endian
    /// CDR, `00 00` big-endian; anything else is refused).
    pub fn with_header(sample: &'a [u8]) -> Result<Self, CdrError> {
        match sample {
            [0, 1, _, _, ..] => Ok(Self::new(&sample[4..], true)),
            [0, 0, _, _, ..] => Ok(Self::new(&sample[4..], false)),
            [a, b, _, _, ..] => Err(CdrError {
                field: "encapsulation",
                offset: 0,
                problem: format!(
                    "representation {a:02x} {b:02x} is not plain CDR (00 00 or 00 01)"
                ),
            }),
            _ => Err(CdrError {
                field: "encapsulation",
                offset: 0,
                problem: format!("{} bytes, fewer than the 4-byte header", sample.len()),
            }),
        }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.body.len() - self.at
    }

    fn error(&self, field: &'static str, problem: String) -> CdrError {
        CdrError {
            field,
            offset: self.at,
            problem,
        }
    }

    fn take(&mut self, field: &'static str, n: usize, align: usize) -> Result<&'a [u8], CdrError> {
        let start = self.at.next_multiple_of(align.max(1));
        let end = start.checked_add(n).filter(|&e| e <= self.body.len());
        match end {
            Some(end) => {
                self.at = end;
                Ok(&self.body[start..end])
            }
            None => Err(self.error(
                field,
                format!(
                    "needs {n} byte(s), {} left: the sample ends early",
                    self.body.len().saturating_sub(start)
                ),
            )),
        }
    }

    read_number!(u16, u16, "A `uint16`.");
    read_number!(u32, u32, "A `uint32`.");
    read_number!(i32, i32, "An `int32`.");
    read_number!(u64, u64, "A `uint64`.");
    read_number!(i64, i64, "An `int64`.");
    read_number!(f32, f32, "A `float32`.");
    read_number!(f64, f64, "A `float64`.");

    /// A `uint8`, `int8`, `byte` or `char`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(field, 1, 1)?[0])
    }

    /// A `bool` (0 or 1).
    pub fn bool(&mut self, field: &'static str) -> Result<bool, CdrError> {
        match self.u8(field)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(self.error(field, format!("{v} is not a bool (0 or 1)"))),
        }
    }

    /// `N` bytes with no alignment (a fixed-size `uint8[N]` array).
    pub fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        Ok(self.take(field, N, 1)?.try_into().expect("N bytes"))
    }

    /// A sequence's count, checked against what is left: each item takes at least
    /// `min_item` bytes, so a count the sample cannot hold is refused before anything is
    /// allocated for it.
    pub fn count(&mut self, field: &'static str, min_item: usize) -> Result<usize, CdrError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(min_item.max(1)) > self.remaining() {
            return Err(self.error(
                field,
                format!(
                    "declares {n} item(s), more than the {} byte(s) left can hold",
                    self.remaining()
                ),
            ));
        }
        Ok(n)
    }

    /// A `string` (UTF-8, NUL-terminated as CDR writes it).
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.count(field, 1)?;
        if n == 0 {
            // Some writers send an empty string as length 0 without the NUL.
            return Ok(String::new());
        }
        let at = self.at;
        let b = self.take(field, n, 1)?;
        if b[n - 1] != 0 {
            self.at = at;
            return Err(self.error(field, "a string without its final NUL".into()));
        }
        String::from_utf8(b[..n - 1].to_vec()).map_err(|_| CdrError {
            field,
            offset: at,
            problem: "a string that is not UTF-8".into(),
        })
    }

    /// A `string[]`.
    pub fn strings(&mut self, field: &'static str) -> Result<Vec<String>, CdrError> {
        let n = self.count(field, 4)?;
        (0..n).map(|_| self.string(field)).collect()
    }

    /// A `float64[]`.
    pub fn f64s(&mut self, field: &'static str) -> Result<Vec<f64>, CdrError> {
        let n = self.count(field, 8)?;
        (0..n).map(|_| self.f64(field)).collect()
    }

    /// A `uint8[]`.
    pub fn bytes(&mut self, field: &'static str) -> Result<Vec<u8>, CdrError> {
        let n = self.count(field, 1)?;
        Ok(self.take(field, n, 1)?.to_vec())
    }

    /// A `builtin_interfaces/Time` or `Duration` as `(sec, nanosec)`.
    pub fn time(&mut self, field: &'static str) -> Result<(i32, u32), CdrError> {
        let sec = self.i32(field)?;
        let nanosec = self.u32(field)?;
        if nanosec >= 1_000_000_000 {
            return Err(self.error(field, format!("nanosec {nanosec} is not below 1e9")));
        }
        Ok((sec, nanosec))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The byte layouts verified against mcap_ros2's own encoder (robot-ready notes §3).
    #[test]
    fn bytes_match_the_reference_encoder() {
        assert_eq!(
            CdrWriter::new().time(1_500_000_000).finish(),
            [0, 1, 0, 0, 1, 0, 0, 0, 0x00, 0x65, 0xcd, 0x1d]
        );
        assert_eq!(
            CdrWriter::new().string("hi").finish(),
            [0, 1, 0, 0, 3, 0, 0, 0, 0x68, 0x69, 0]
        );
        let names = vec!["a".to_string(), "bc".to_string()];
        let m = CdrWriter::new()
            .header(7_000_000_000, "base")
            .strings(&names)
            .f64s(&[1.0, 2.0])
            .f64s(&[0.25, -0.5])
            .f64s(&[])
            .finish();
        assert_eq!(m.len(), 96);
        let p = &m[4..];
        assert_eq!(p[0..4], 7i32.to_le_bytes());
        assert_eq!(p[8..12], 5u32.to_le_bytes());
        assert_eq!(&p[12..17], b"base\0");
        assert_eq!(p[20..24], 2u32.to_le_bytes());
        assert_eq!(p[40..44], 2u32.to_le_bytes());
        assert_eq!(p[48..56], 1.0f64.to_le_bytes());
        assert_eq!(p[80..88], (-0.5f64).to_le_bytes());
        assert_eq!(p[88..92], 0u32.to_le_bytes());

        let mut r = CdrReader::with_header(&m).unwrap();
        assert_eq!(r.time("stamp").unwrap(), (7, 0));
        assert_eq!(r.string("frame_id").unwrap(), "base");
        assert_eq!(r.strings("name").unwrap(), names);
        assert_eq!(r.f64s("position").unwrap(), [1.0, 2.0]);
        assert_eq!(r.f64s("velocity").unwrap(), [0.25, -0.5]);
        assert!(r.f64s("effort").unwrap().is_empty());
        assert_eq!(r.remaining(), 0);
    }

    #[test]
    fn big_endian_samples_read_the_same_numbers() {
        let body = [
            0, 0, 0, 2, 0, 0, 0, 0, 0x3f, 0xf0, 0, 0, 0, 0, 0, 0, 0xc0, 0, 0, 0, 0, 0, 0, 0,
        ];
        let mut sample = vec![0, 0, 0, 0];
        sample.extend_from_slice(&body);
        let mut r = CdrReader::with_header(&sample).unwrap();
        assert_eq!(r.f64s("x").unwrap(), [1.0, -2.0]);
    }

    #[test]
    fn lies_about_sizes_are_refused_before_allocating() {
        // A sequence of 2^32 - 1 doubles in a 12-byte sample.
        let m = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff, 0, 0, 0, 0];
        let e = CdrReader::with_header(&m)
            .unwrap()
            .f64s("position")
            .unwrap_err();
        assert_eq!(e.field, "position");
        assert!(e.problem.contains("4294967295 item(s)"), "{e}");
        // A string running past the end.
        let m = [0, 1, 0, 0, 9, 0, 0, 0, b'a', b'b'];
        let e = CdrReader::with_header(&m)
            .unwrap()
            .string("frame_id")
            .unwrap_err();
        assert!(e.to_string().contains("frame_id"), "{e}");
        // A string without its NUL, a bad bool, a bad nanosecond count, XCDR2.
        let m = [0, 1, 0, 0, 2, 0, 0, 0, b'a', b'b'];
        assert!(CdrReader::with_header(&m).unwrap().string("s").is_err());
        assert!(CdrReader::new(&[2], true).bool("accepted").is_err());
        let t = CdrWriter::new().i32(1).u32(1_000_000_000).finish();
        assert!(CdrReader::with_header(&t).unwrap().time("stamp").is_err());
        assert!(CdrReader::with_header(&[0, 7, 0, 0]).is_err());
        assert!(CdrReader::with_header(&[0, 1]).is_err());
    }
}
