//! The parquet reader (the crate's `parquet` feature): columns by name, row by row.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::file::statistics::Statistics;
use parquet::record::{Field, Row};
use parquet::schema::types::Type;

use super::{Cell, MAX_PARQUET_BYTES};
use crate::error::LeRobotError;

fn cell(f: &Field) -> Cell {
    match f {
        Field::Null => Cell::Null,
        Field::Bool(b) => Cell::Int(i64::from(*b)),
        Field::Byte(v) => Cell::Int(i64::from(*v)),
        Field::Short(v) => Cell::Int(i64::from(*v)),
        Field::Int(v) => Cell::Int(i64::from(*v)),
        Field::Long(v) => Cell::Int(*v),
        Field::UByte(v) => Cell::Int(i64::from(*v)),
        Field::UShort(v) => Cell::Int(i64::from(*v)),
        Field::UInt(v) => Cell::Int(i64::from(*v)),
        Field::ULong(v) => i64::try_from(*v).map_or(Cell::Num(*v as f64), Cell::Int),
        Field::Float16(v) => Cell::Num(f64::from(f32::from(*v))),
        Field::Float(v) => Cell::Num(f64::from(*v)),
        Field::Double(v) => Cell::Num(*v),
        Field::Str(s) => Cell::Text(s.clone()),
        Field::ListInternal(list) => Cell::List(list.elements().iter().map(cell).collect()),
        _ => Cell::Null,
    }
}

/// The parquet file at `path`, opened (a regular file within [`MAX_PARQUET_BYTES`]).
pub fn open(path: &Path) -> Result<SerializedFileReader<File>, LeRobotError> {
    if !path.exists() {
        return Err(LeRobotError::new(path, "missing"));
    }
    let (file, _) = cps_files::read::open(path, MAX_PARQUET_BYTES, "parquet file")?;
    SerializedFileReader::new(file).map_err(|e| {
        LeRobotError::new(
            path,
            format!("not a readable parquet file ({e}); is it truncated?"),
        )
    })
}

pub(super) fn read_unguarded(
    path: &Path,
    columns: &[&str],
    filter: Option<(&str, std::ops::RangeInclusive<i64>)>,
) -> Result<Vec<Vec<Cell>>, LeRobotError> {
    let reader = open(path)?;
    let schema = reader.metadata().file_metadata().schema();
    let mut fields: Vec<Arc<Type>> = Vec::new();
    for name in columns {
        let field = schema
            .get_fields()
            .iter()
            .find(|f| f.name() == *name)
            .ok_or_else(|| {
                let have: Vec<&str> = schema.get_fields().iter().map(|f| f.name()).collect();
                LeRobotError::new(
                    path,
                    format!("has no column `{name}` (its columns: {})", have.join(", ")),
                )
            })?;
        fields.push(field.clone());
    }
    let projection = Type::group_type_builder(schema.name())
        .with_fields(fields)
        .build()
        .map_err(|e| LeRobotError::new(path, format!("its schema: {e}")))?;
    let broken = |e: parquet::errors::ParquetError| {
        LeRobotError::new(path, format!("cannot be read ({e}); is it truncated?"))
    };
    let mut rows = Vec::new();
    let filter_at = filter
        .as_ref()
        .map(|(name, _)| columns.iter().position(|c| c == name).unwrap_or(usize::MAX));
    for g in 0..reader.num_row_groups() {
        let group = reader.get_row_group(g).map_err(broken)?;
        if let Some((name, keep)) = &filter
            && let Some((lo, hi)) = int_range(group.metadata(), name)
            && (hi < *keep.start() || lo > *keep.end())
        {
            continue;
        }
        for row in group
            .get_row_iter(Some(projection.clone()))
            .map_err(broken)?
        {
            let row: Row = row.map_err(broken)?;
            let cells: Vec<Cell> = row.get_column_iter().map(|(_, f)| cell(f)).collect();
            if let (Some((_, keep)), Some(at)) = (&filter, filter_at) {
                match cells.get(at) {
                    Some(Cell::Int(v)) if keep.contains(v) => {}
                    _ => continue,
                }
            }
            rows.push(cells);
        }
    }
    Ok(rows)
}

/// The smallest and largest value of a whole-number column in a row group, when its
/// statistics say.
fn int_range(meta: &parquet::file::metadata::RowGroupMetaData, name: &str) -> Option<(i64, i64)> {
    let col = meta
        .columns()
        .iter()
        .find(|c| c.column_path().string() == name)?;
    match col.statistics()? {
        Statistics::Int64(s) => Some((*s.min_opt()?, *s.max_opt()?)),
        Statistics::Int32(s) => Some((i64::from(*s.min_opt()?), i64::from(*s.max_opt()?))),
        _ => None,
    }
}
