//! OptiTrack Motive's CSV export (format versions 1.2x, Motive 2 and 3), read by cps.
//!
//! Layout as Motive writes it: line 1 holds `key,value` pairs (`Format Version`,
//! `Take Name`, `Capture Frame Rate`, `Export Frame Rate`, `Total Exported Frames`,
//! `Rotation Type`, `Length Units`, `Coordinate Space`…); a blank line; then header rows
//! labelled in their first or second cell — `Type` (`Rigid Body`, `Rigid Body Marker`,
//! `Marker`, `Bone`…), `Name`, `ID`, optionally `Parent` — and an unlabelled row naming
//! each column's quantity (`Rotation`, `Position`, `Mean Marker Error`,
//! `Marker Quality`); the axis row `Frame,Time (Seconds),X,Y,Z,W,…`; then one row per
//! frame, an occluded value left empty. Rigid bodies are position + quaternion
//! `(X, Y, Z, W)` when exported with `Rotation Type` `Quaternion`.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::MocapError;
use crate::take::{RigidBodyTrack, Source, Take, metres_per_unit};

/// Reads a Motive CSV export.
pub fn read(path: &Path) -> Result<Take, MocapError> {
    let (bytes, name) = crate::take::read_file(path)?;
    parse(&bytes, &name)
}

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    Marker,
    SolvedMarker,
    RigidBody,
}

/// Parses the bytes of a Motive CSV export (`file` names it in messages).
// Long on purpose (over 150 lines): it reads the export in the order of its rows (the
// take's settings, the header rows up to the axis row, the frames), each check beside
// the row it guards.
pub fn parse(bytes: &[u8], file: &str) -> Result<Take, MocapError> {
    let bad = |m: String| MocapError::format(file, m);
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes);
    let mut rows = reader.records();
    let mut next = |what: &str| -> Result<Option<(u64, csv::StringRecord)>, MocapError> {
        match rows.next() {
            None => Ok(None),
            Some(Ok(r)) => Ok(Some((r.position().map_or(0, |p| p.line()), r))),
            Some(Err(e)) => Err(bad(format!("{what}: {e}"))),
        }
    };
    let (_, meta_row) = next("line 1")?.ok_or_else(|| bad("the file is empty".into()))?;
    let meta: BTreeMap<String, String> = meta_row
        .iter()
        .collect::<Vec<_>>()
        .chunks(2)
        .filter(|c| c.len() == 2)
        .map(|c| (c[0].trim().to_string(), c[1].trim().to_string()))
        .collect();
    if !meta.contains_key("Format Version") {
        return Err(bad(
            "line 1 has no `Format Version`: not a Motive CSV export (its first line starts `Format Version,1.2x,Take Name,…`)"
                .into(),
        ));
    }
    // Header rows up to the axis row.
    let mut header: Vec<(u64, csv::StringRecord)> = Vec::new();
    let axis = loop {
        let Some((line, r)) = next("the header")? else {
            return Err(bad(
                "no `Frame,Time (Seconds),…` row: the header ends before the data".into(),
            ));
        };
        let first = r.get(0).unwrap_or("").trim();
        if first.eq_ignore_ascii_case("Frame") && r.get(1).unwrap_or("").trim().starts_with("Time")
        {
            break (line, r);
        }
        if r.iter().any(|c| !c.trim().is_empty()) {
            header.push((line, r));
        }
        if header.len() > 20 {
            return Err(bad(format!(
                "line {line}: still no `Frame,Time (Seconds),…` row after 20 header rows"
            )));
        }
    };
    let (axis_line, axis) = axis;
    // Columns from 2 (or 3 with a TimeCode column) on.
    let first_col = 2 + usize::from(axis.get(2).is_some_and(|c| c.trim() == "TimeCode"));
    let label_of = |r: &csv::StringRecord| -> String {
        let a = r.get(0).unwrap_or("").trim();
        let b = r.get(1).unwrap_or("").trim();
        if a.is_empty() {
            b.to_string()
        } else {
            a.to_string()
        }
    };
    let mut types: Option<&csv::StringRecord> = None;
    let mut names: Option<&csv::StringRecord> = None;
    let mut quantities: Option<&csv::StringRecord> = None;
    let mut unlabelled = Vec::new();
    for (_, r) in &header {
        match label_of(r).as_str() {
            "Type" => types = Some(r),
            "Name" => names = Some(r),
            "ID" | "Parent" => {}
            "" => {
                let cells: Vec<&str> = r.iter().skip(first_col).map(str::trim).collect();
                if cells.iter().any(|c| *c == "Position" || *c == "Rotation") {
                    quantities = Some(r);
                } else {
                    unlabelled.push(r);
                }
            }
            _ => unlabelled.push(r),
        }
    }
    // Older exports leave the rows unlabelled: Type, Name, ID in that order.
    let mut rest = unlabelled.into_iter();
    if types.is_none() {
        types = rest.next();
    }
    if names.is_none() {
        names = rest.next();
    }
    let (Some(types), Some(names), Some(quantities)) = (types, names, quantities) else {
        return Err(bad(format!(
            "lines 3–{}: the header needs a `Type` row, a `Name` row and a row of `Position`/`Rotation`",
            axis_line.saturating_sub(1)
        )));
    };
    let cell = |r: &csv::StringRecord, c: usize| r.get(c).unwrap_or("").trim().to_string();
    // (kind, name) → axis → column.
    let mut objects: BTreeMap<(String, Kind), BTreeMap<String, usize>> = BTreeMap::new();
    let mut order: Vec<(String, Kind)> = Vec::new();
    for c in first_col..axis.len() {
        let kind = match cell(types, c).as_str() {
            "Marker" => Kind::Marker,
            "Rigid Body Marker" => Kind::SolvedMarker,
            "Rigid Body" => Kind::RigidBody,
            _ => continue,
        };
        let quantity = cell(quantities, c);
        let ax = cell(&axis, c).to_ascii_uppercase();
        let key = match (kind, quantity.as_str()) {
            (Kind::RigidBody, "Rotation") => format!("r{ax}"),
            (_, "Position") => format!("p{ax}"),
            (_, "Mean Marker Error" | "Marker Error") => "err".to_string(),
            _ => continue,
        };
        let id = (cell(names, c), kind);
        if !objects.contains_key(&id) {
            order.push(id.clone());
        }
        objects.entry(id).or_default().insert(key, c);
    }
    let rotation_type = meta
        .get("Rotation Type")
        .cloned()
        .unwrap_or_else(|| "Quaternion".into());
    let units = meta
        .get("Length Units")
        .cloned()
        .unwrap_or_else(|| "Meters".into());
    let metres = metres_per_unit(&units).ok_or_else(|| {
        bad(format!(
            "line 1: `Length Units` is \"{units}\"; cps reads Meters, Centimeters and Millimeters"
        ))
    })?;
    let rate_key = ["Export Frame Rate", "Capture Frame Rate"]
        .into_iter()
        .find(|k| meta.contains_key(*k))
        .ok_or_else(|| bad("line 1 gives no `Export Frame Rate` or `Capture Frame Rate`".into()))?;
    let rate: f64 = meta[rate_key]
        .parse()
        .ok()
        .filter(|r: &f64| r.is_finite() && *r > 0.0)
        .ok_or_else(|| {
            bad(format!(
                "line 1: `{rate_key}` is \"{}\", not a positive number",
                meta[rate_key]
            ))
        })?;

    // Markers: Motive's own ("Marker"), and solved rigid-body markers whose name no raw
    // marker has.
    let raw: std::collections::HashSet<String> = order
        .iter()
        .filter(|(_, k)| *k == Kind::Marker)
        .map(|(n, _)| n.clone())
        .collect();
    let markers: Vec<(String, [usize; 3])> = order
        .iter()
        .filter(|(n, k)| *k == Kind::Marker || (*k == Kind::SolvedMarker && !raw.contains(n)))
        .filter_map(|id| {
            let a = &objects[id];
            Some((id.0.clone(), [*a.get("pX")?, *a.get("pY")?, *a.get("pZ")?]))
        })
        .collect();
    struct Body {
        name: String,
        p: [usize; 3],
        q: Option<[usize; 4]>,
    }
    let bodies: Vec<Body> = order
        .iter()
        .filter(|(_, k)| *k == Kind::RigidBody)
        .filter_map(|id| {
            let a = &objects[id];
            let q = match (a.get("rX"), a.get("rY"), a.get("rZ"), a.get("rW")) {
                (Some(&x), Some(&y), Some(&z), Some(&w)) => Some([x, y, z, w]),
                _ => None,
            };
            Some(Body {
                name: id.0.clone(),
                p: [*a.get("pX")?, *a.get("pY")?, *a.get("pZ")?],
                q,
            })
        })
        .collect();
    let mut notes = Vec::new();
    if bodies.iter().any(|b| b.q.is_none()) {
        notes.push(format!(
            "rigid-body rotations are Euler angles (`Rotation Type` {rotation_type}); export with Rotation Type Quaternion to use them"
        ));
    }

    let m = markers.len();
    let mut xyz: Vec<[f32; 3]> = Vec::new();
    let mut residual: Vec<f32> = Vec::new();
    let mut tracks: Vec<RigidBodyTrack> = bodies
        .iter()
        .map(|b| RigidBodyTrack {
            name: b.name.clone(),
            position: Vec::new(),
            quaternion: Vec::new(),
        })
        .collect();
    let mut frames = 0usize;
    let mut first_frame = None;
    let mut record = csv::StringRecord::new();
    loop {
        match reader.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => return Err(bad(format!("after line {axis_line}: {e}"))),
        }
        let line = record.position().map_or(0, |p| p.line());
        if record.iter().all(|c| c.trim().is_empty()) {
            continue;
        }
        let number = |c: usize| -> Result<f64, MocapError> {
            let s = record.get(c).unwrap_or("").trim();
            if s.is_empty() {
                return Ok(f64::NAN);
            }
            s.parse::<f64>().map_err(|_| {
                bad(format!(
                    "line {line}, column {} ({} {}): \"{s}\" is not a number",
                    c + 1,
                    cell(names, c),
                    cell(&axis, c)
                ))
            })
        };
        if first_frame.is_none() {
            let f = number(0)?;
            if !(0.0..=4e9).contains(&f) && !f.is_nan() {
                return Err(bad(format!(
                    "line {line}: frame number {f} is not a frame number (0 to 4 000 000 000)"
                )));
            }
            first_frame = Some(if f.is_nan() { 0 } else { f as u64 });
        }
        for (_, cols) in &markers {
            let p = [number(cols[0])?, number(cols[1])?, number(cols[2])?];
            if p.iter().all(|v| v.is_finite()) {
                xyz.push(p.map(|v| v as f32));
                residual.push(0.0);
            } else {
                xyz.push([f32::NAN; 3]);
                residual.push(-1.0);
            }
        }
        for (b, t) in bodies.iter().zip(tracks.iter_mut()) {
            t.position
                .push([number(b.p[0])?, number(b.p[1])?, number(b.p[2])?]);
            t.quaternion.push(match b.q {
                Some(q) => [number(q[0])?, number(q[1])?, number(q[2])?, number(q[3])?],
                None => [f64::NAN; 4],
            });
        }
        frames += 1;
    }
    if frames == 0 {
        return Err(bad(format!("no data rows after line {axis_line}")));
    }
    Ok(Take {
        file: file.to_string(),
        source: Source::MotiveCsv,
        labels: markers.into_iter().map(|(n, _)| n).collect(),
        rate,
        first_frame: first_frame.unwrap_or(0),
        frames,
        units,
        metres_per_unit: metres,
        xyz,
        residual,
        analog: None,
        rigid_bodies: tracks,
        notes,
    })
    .inspect(|t| debug_assert_eq!(t.xyz.len(), t.frames * m))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(header: &str, rows: &[&str]) -> Vec<u8> {
        let mut s = String::from(header);
        for r in rows {
            s.push_str(r);
            s.push('\n');
        }
        s.into_bytes()
    }

    #[test]
    fn unlabelled_header_rows_and_a_timecode_column_are_read() {
        // An older export: no `Type`/`Name` labels, a TimeCode column, metres by default.
        let b = file(
            "Format Version,1.21,Take Name,x,Export Frame Rate,100.000000\n\n,,,Marker,Marker,Marker,Marker,Marker,Marker\n,,,Hand:Thumb,Hand:Thumb,Hand:Thumb,Hand:Index,Hand:Index,Hand:Index\n,,,1,1,1,2,2,2\n,,,Position,Position,Position,Position,Position,Position\nFrame,Time (Seconds),TimeCode,X,Y,Z,X,Y,Z\n",
            &[
                "0,0.000000,15:26:46:12.02,1,2,3,4,5,6",
                "1,0.010000,15:26:46:12.03,7,8,9,,,",
            ],
        );
        let t = parse(&b, "old.csv").unwrap();
        assert_eq!(t.labels, ["Hand:Thumb", "Hand:Index"]);
        assert_eq!((t.rate, t.frames, t.metres_per_unit), (100.0, 2, 1.0));
        assert_eq!(t.point(1, 0), [7.0, 8.0, 9.0]);
        assert!(t.seen(0, 1) && !t.seen(1, 1));
        assert_eq!(t.find_label("Index"), Some(1));
    }

    #[test]
    fn euler_rigid_bodies_and_bad_cells_are_named() {
        let header = "Format Version,1.23,Capture Frame Rate,120.000000,Rotation Type,XYZ,Length Units,Millimeters\n\n,Type,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body\n,Name,Tool,Tool,Tool,Tool,Tool,Tool\n,ID,1,1,1,1,1,1\n,,Rotation,Rotation,Rotation,Position,Position,Position\nFrame,Time (Seconds),X,Y,Z,X,Y,Z\n";
        let t = parse(&file(header, &["0,0,10,20,30,1,2,3"]), "euler.csv").unwrap();
        assert!(t.notes[0].contains("Euler"), "{:?}", t.notes);
        let e = parse(&file(header, &["0,0,10,20,30,1,two,3"]), "bad.csv")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("bad.csv: line 8, column 7 (Tool Y)"), "{e}");
        let e = parse(b"Frame,Time\n1,2\n", "plain.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a Motive CSV export"), "{e}");
        let e = parse(
            header.replace("Millimeters", "Furlongs").as_bytes(),
            "u.csv",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("Furlongs"), "{e}");
    }
}
