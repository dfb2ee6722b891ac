//! A recorded stream of action chunks as a CSV file, to replay and tune a policy's
//! execution offline: one row per target, `chunk, arrived_s, observed_s, k, q1..qn` — the
//! chunk's number, when it arrived and when the observation it was predicted from was
//! taken (seconds, one clock), the target's index in its chunk (0, 1, …) and its joint
//! positions (rad). The chunks' rate is given beside the file. Every row of a chunk
//! carries the same times; chunks come in arrival order, numbered upwards.
//!
//! Anything else is refused with the file, the line and what is wrong there.

use std::path::Path;

use cps_chunks::Chunk;
use cps_outcome::InputError;

/// The largest chunk file read (bytes).
pub const MAX_CHUNK_FILE_BYTES: u64 = 256 << 20;

/// The header of a chunk file for `dof` joints.
pub fn header(dof: usize) -> String {
    let mut h = String::from("chunk,arrived_s,observed_s,k");
    for j in 1..=dof {
        h.push_str(&format!(",q{j}"));
    }
    h
}

/// Chunks as a chunk file's text (numbered from 0 in their order).
pub fn write_chunks(chunks: &[Chunk], dof: usize) -> String {
    let mut out = Vec::new();
    out.extend_from_slice(header(dof).as_bytes());
    out.push(b'\n');
    for (i, c) in chunks.iter().enumerate() {
        write_chunk(&mut out, i, c).expect("writing to memory");
    }
    String::from_utf8(out).expect("the rows are ASCII")
}

/// One chunk's rows of a chunk file (`id, arrived_s, observed_s, k, q…` per target): what
/// a stream writes as its chunks come back, so a long run never holds them all.
pub fn write_chunk(out: &mut impl std::io::Write, id: usize, c: &Chunk) -> std::io::Result<()> {
    for (k, q) in c.targets.iter().enumerate() {
        write!(out, "{id},{},{},{k}", c.arrived_s, c.observed_s)?;
        for v in q {
            write!(out, ",{v}")?;
        }
        writeln!(out)?;
    }
    Ok(())
}

/// The chunk being read: its number, arrival, observation, first line and targets.
type Open = (u64, f64, f64, usize, Vec<Vec<f64>>);

/// The chunks of a chunk file for a robot of `dof` joints, at `rate_hz` targets per
/// second (see the module's text).
pub fn read_chunks(path: &Path, dof: usize, rate_hz: f64) -> Result<Vec<Chunk>, InputError> {
    let text = cps_outcome::source::read_text(path, MAX_CHUNK_FILE_BYTES, "chunk file")?;
    parse_chunks(path, &text, dof, rate_hz)
}

/// [`read_chunks`] of text already read (`path` names it in messages).
pub fn parse_chunks(
    path: &Path,
    text: &str,
    dof: usize,
    rate_hz: f64,
) -> Result<Vec<Chunk>, InputError> {
    let at = |line: usize, m: String| InputError(format!("{}:{line}: {m}", path.display()));
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let want = header(dof);
    match lines.next() {
        Some((_, h)) if h.split(',').map(str::trim).eq(want.split(',')) => {}
        Some((n, h)) => {
            return Err(at(
                n,
                format!("the header is `{h}`; a chunk file for {dof} joints has `{want}`"),
            ));
        }
        None => return Err(at(1, format!("the file is empty; its header is `{want}`"))),
    }
    let mut chunks: Vec<Chunk> = Vec::new();
    let mut open: Option<Open> = None;
    let close = |open: Option<Open>, chunks: &mut Vec<Chunk>| -> Result<(), InputError> {
        if let Some((_, arrived, observed, line, targets)) = open {
            // A chunk whose times go back against the one before is the executor's to
            // refuse, live as in a replay, while the arm keeps its motion.
            let c = Chunk::new(observed, arrived, rate_hz, targets, None, dof)
                .map_err(|e| at(line, e.to_string()))?;
            chunks.push(c);
        }
        Ok(())
    };
    for (n, line) in lines {
        if line.is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != 4 + dof {
            return Err(at(
                n,
                format!(
                    "{} value(s); a row has 4 + {dof}: chunk, arrived_s, observed_s, k, then the joints",
                    cells.len()
                ),
            ));
        }
        let number = |i: usize, name: &str| -> Result<f64, InputError> {
            cells[i]
                .parse::<f64>()
                .map_err(|_| at(n, format!("{name} `{}` is not a number", cells[i])))
        };
        let whole = |i: usize, name: &str| -> Result<u64, InputError> {
            cells[i].parse::<u64>().map_err(|_| {
                at(
                    n,
                    format!("{name} `{}` is not a whole number ≥ 0", cells[i]),
                )
            })
        };
        let (id, arrived, observed, k) = (
            whole(0, "chunk")?,
            number(1, "arrived_s")?,
            number(2, "observed_s")?,
            whole(3, "k")?,
        );
        let q = (0..dof)
            .map(|j| number(4 + j, &format!("q{}", j + 1)))
            .collect::<Result<Vec<f64>, _>>()?;
        match &mut open {
            Some((open_id, a, o, _, targets)) if *open_id == id => {
                if arrived != *a || observed != *o {
                    return Err(at(
                        n,
                        format!(
                            "chunk {id} arrived at {a} s from an observation at {o} s; this row says {arrived} s and {observed} s"
                        ),
                    ));
                }
                if k as usize != targets.len() {
                    return Err(at(
                        n,
                        format!(
                            "k = {k} in chunk {id}, whose next target is k = {}",
                            targets.len()
                        ),
                    ));
                }
                targets.push(q);
            }
            _ => {
                if let Some((open_id, ..)) = &open
                    && id <= *open_id
                {
                    return Err(at(
                        n,
                        format!(
                            "chunk {id} after chunk {open_id}: chunks are numbered upwards, each in one run of rows"
                        ),
                    ));
                }
                if k != 0 {
                    return Err(at(
                        n,
                        format!("chunk {id} starts at k = {k}; its first target is k = 0"),
                    ));
                }
                close(open.take(), &mut chunks)?;
                open = Some((id, arrived, observed, n, vec![q]));
            }
        }
    }
    close(open, &mut chunks)?;
    if chunks.is_empty() {
        return Err(InputError(format!(
            "{}: no chunk in the file",
            path.display()
        )));
    }
    Ok(chunks)
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = "chunk,arrived_s,observed_s,k,q1,q2
0,0.12,0.0,0,0.0,0.1
0,0.12,0.0,1,0.01,0.11
1,0.45,0.33,0,0.02,0.12
1,0.45,0.33,1,0.03,0.13
1,0.45,0.33,2,0.04,0.14
";

    fn parse(text: &str) -> Result<Vec<Chunk>, InputError> {
        parse_chunks(Path::new("c.csv"), text, 2, 30.0)
    }

    #[test]
    fn a_chunk_file_reads_and_writes_back_the_same() {
        let chunks = parse(FILE).unwrap();
        assert_eq!(chunks.len(), 2);
        assert_eq!(
            chunks[1].targets,
            [[0.02, 0.12], [0.03, 0.13], [0.04, 0.14]]
        );
        assert!((chunks[1].delay() - 0.12).abs() < 1e-12);
        assert_eq!(chunks[0].rate_hz, 30.0);
        assert_eq!(parse(&write_chunks(&chunks, 2)).unwrap(), chunks);
    }

    #[test]
    fn a_bad_chunk_file_is_refused_at_its_line() {
        let cases = [
            ("", "c.csv:1: the file is empty"),
            (
                "t,q1,q2\n",
                "c.csv:1: the header is `t,q1,q2`; a chunk file for 2 joints has `chunk,arrived_s,observed_s,k,q1,q2`",
            ),
            (
                "chunk,arrived_s,observed_s,k,q1,q2\n",
                "c.csv: no chunk in the file",
            ),
            ("0,0.12,0.0,0,0.0\n", "c.csv:2: 5 value(s); a row has 4 + 2"),
            ("0,0.12,0.0,0,0.0,x\n", "c.csv:2: q2 `x` is not a number"),
            (
                "0,0.12,0.0,0,0.0,NaN\n",
                "c.csv:2: target 0 of the chunk, joint 2: NaN is not a number",
            ),
            (
                "-1,0.12,0.0,0,0.0,0.0\n",
                "c.csv:2: chunk `-1` is not a whole number",
            ),
            ("0,0.12,0.0,1,0.0,0.0\n", "c.csv:2: chunk 0 starts at k = 1"),
            (
                "0,0.12,0.0,0,0,0\n0,0.12,0.0,2,0,0\n",
                "c.csv:3: k = 2 in chunk 0, whose next target is k = 1",
            ),
            (
                "0,0.12,0.0,0,0,0\n0,0.13,0.0,1,0,0\n",
                "c.csv:3: chunk 0 arrived at 0.12 s from an observation at 0 s; this row says 0.13 s and 0 s",
            ),
            (
                "1,0.12,0.0,0,0,0\n0,0.2,0.1,0,0,0\n",
                "c.csv:3: chunk 0 after chunk 1",
            ),
            (
                "0,0.05,0.1,0,0,0\n",
                "c.csv:2: the chunk arrived at 0.05 s, before the observation it was predicted from (0.1 s)",
            ),
        ];
        for (rows, says) in cases {
            let text = if rows.starts_with("t,") || rows.is_empty() || rows.starts_with("chunk,") {
                rows.to_string()
            } else {
                format!("chunk,arrived_s,observed_s,k,q1,q2\n{rows}")
            };
            let e = parse(&text).unwrap_err().0;
            assert!(e.starts_with(says), "{rows:?}: {e}");
        }
        // Observation times that go back once (parallel inference servers' delays of 70–130
        // ms at 30 Hz) are read: the executor refuses that chunk alone, the arm moving on.
        let stale =
            parse("chunk,arrived_s,observed_s,k,q1,q2\n0,0.2,0.1,0,0,0\n1,0.3,0.05,0,0,0\n");
        assert_eq!(stale.unwrap().len(), 2);
        let e = parse_chunks(Path::new("c.csv"), FILE, 2, -1.0)
            .unwrap_err()
            .0;
        assert!(
            e.starts_with("c.csv:2: the chunk's rate -1 Hz is not a rate"),
            "{e}"
        );
    }
}
