//! The dataset's files written (the crate's `parquet` feature): frames, episodes and
//! tasks as parquet, the statistics and `meta/info.json`.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use parquet::basic::{Compression, ConvertedType, LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArray, ByteArrayType, FloatType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use serde_json::{Map, Value, json};

use crate::error::LeRobotError;

use super::{BOOKKEEPING, DATA_FILE, EPISODES_FILE, NewDataset, NewEpisode};

fn io(path: &Path) -> impl Fn(std::io::Error) -> LeRobotError + '_ {
    move |e| LeRobotError::new(path, format!("cannot be written: {e}"))
}

fn pq(path: &Path) -> impl Fn(parquet::errors::ParquetError) -> LeRobotError + '_ {
    move |e| LeRobotError::new(path, format!("cannot be written as parquet: {e}"))
}

pub(super) fn write_into(
    dir: &Path,
    spec: &NewDataset,
    episodes: &[NewEpisode],
) -> Result<(), LeRobotError> {
    for sub in ["data/chunk-000", "meta/episodes/chunk-000"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(io(dir))?;
    }
    let mut tasks: Vec<String> = Vec::new();
    for ep in episodes {
        if !tasks.contains(&ep.task) {
            tasks.push(ep.task.clone());
        }
    }
    let task_of = |ep: &NewEpisode| tasks.iter().position(|t| *t == ep.task).unwrap_or(0) as i64;
    write_frames(&dir.join(DATA_FILE), spec, episodes, &task_of)?;
    write_episodes(&dir.join(EPISODES_FILE), episodes)?;
    write_tasks(&dir.join(crate::dataset::TASKS_PATH), &tasks)?;
    let stats = statistics(spec, episodes, &task_of);
    let stats_path = dir.join("meta/stats.json");
    std::fs::write(
        &stats_path,
        serde_json::to_string_pretty(&stats).unwrap_or_default(),
    )
    .map_err(io(&stats_path))?;
    let info_path = dir.join(crate::info::INFO_PATH);
    let info = info_json(spec, episodes, tasks.len());
    std::fs::write(
        &info_path,
        serde_json::to_string_pretty(&info).unwrap_or_default(),
    )
    .map_err(io(&info_path))
}

/// `meta/info.json` as LeRobot 0.6 writes it.
fn info_json(spec: &NewDataset, episodes: &[NewEpisode], tasks: usize) -> Value {
    let mut features = Map::new();
    for f in &spec.features {
        features.insert(
            f.name.clone(),
            json!({"dtype": "float32", "shape": [f.names.len()], "names": f.names}),
        );
    }
    features.insert(
        "timestamp".into(),
        json!({"dtype": "float32", "shape": [1], "names": null}),
    );
    for key in BOOKKEEPING {
        features.insert(
            key.into(),
            json!({"dtype": "int64", "shape": [1], "names": null}),
        );
    }
    json!({
        "codebase_version": "v3.0",
        "robot_type": spec.robot_type,
        "total_episodes": episodes.len(),
        "total_frames": episodes.iter().map(NewEpisode::len).sum::<usize>(),
        "total_tasks": tasks,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": spec.fps,
        "splits": {"train": format!("0:{}", episodes.len())},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": null,
        "features": features,
    })
}

fn optional(
    t: parquet::schema::types::PrimitiveTypeBuilder<'_>,
) -> parquet::schema::types::PrimitiveTypeBuilder<'_> {
    t.with_repetition(Repetition::OPTIONAL)
}

/// A list column as pyarrow writes one: `optional group NAME (LIST) { repeated group list
/// { optional ELEMENT element; } }`.
fn list_of(name: &str, element: Type) -> parquet::errors::Result<Type> {
    let list = Type::group_type_builder("list")
        .with_repetition(Repetition::REPEATED)
        .with_fields(vec![Arc::new(element)])
        .build()?;
    Type::group_type_builder(name)
        .with_repetition(Repetition::OPTIONAL)
        .with_logical_type(Some(LogicalType::List))
        .with_converted_type(ConvertedType::LIST)
        .with_fields(vec![Arc::new(list)])
        .build()
}

fn float_element() -> parquet::errors::Result<Type> {
    optional(Type::primitive_type_builder("element", Physical::FLOAT)).build()
}

fn text(name: &str) -> parquet::errors::Result<Type> {
    optional(Type::primitive_type_builder(name, Physical::BYTE_ARRAY))
        .with_logical_type(Some(LogicalType::String))
        .with_converted_type(ConvertedType::UTF8)
        .build()
}

fn scalar(name: &str, physical: Physical) -> parquet::errors::Result<Type> {
    optional(Type::primitive_type_builder(name, physical)).build()
}

/// One column's values, row by row.
enum Column {
    Lists(Vec<Vec<f32>>),
    Texts(Vec<Vec<String>>),
    Floats(Vec<f32>),
    Ints(Vec<i64>),
    Text(Vec<String>),
}

fn new_file(
    path: &Path,
    fields: Vec<Type>,
    metadata: Vec<KeyValue>,
) -> Result<SerializedFileWriter<File>, LeRobotError> {
    let schema = Type::group_type_builder("schema")
        .with_fields(fields.into_iter().map(Arc::new).collect())
        .build()
        .map_err(pq(path))?;
    let props = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_key_value_metadata((!metadata.is_empty()).then_some(metadata))
        .build();
    let file = File::create(path).map_err(io(path))?;
    SerializedFileWriter::new(file, Arc::new(schema), Arc::new(props)).map_err(pq(path))
}

/// Writes one row group of `columns` (in the schema's order).
fn row_group(
    writer: &mut SerializedFileWriter<File>,
    path: &Path,
    columns: Vec<Column>,
) -> Result<(), LeRobotError> {
    let mut rg = writer.next_row_group().map_err(pq(path))?;
    for column in columns {
        let mut col = rg
            .next_column()
            .map_err(pq(path))?
            .ok_or_else(|| LeRobotError::new(path, "the schema has fewer columns than written"))?;
        match column {
            Column::Lists(rows) => {
                let (mut values, mut def, mut rep) = (Vec::new(), Vec::new(), Vec::new());
                for row in rows {
                    for (i, v) in row.into_iter().enumerate() {
                        values.push(v);
                        def.push(3);
                        rep.push(i16::from(i > 0));
                    }
                }
                col.typed::<FloatType>()
                    .write_batch(&values, Some(&def), Some(&rep))
                    .map_err(pq(path))?;
            }
            Column::Texts(rows) => {
                let (mut values, mut def, mut rep) = (Vec::new(), Vec::new(), Vec::new());
                for row in rows {
                    for (i, v) in row.into_iter().enumerate() {
                        values.push(ByteArray::from(v.into_bytes()));
                        def.push(3);
                        rep.push(i16::from(i > 0));
                    }
                }
                col.typed::<ByteArrayType>()
                    .write_batch(&values, Some(&def), Some(&rep))
                    .map_err(pq(path))?;
            }
            Column::Floats(v) => {
                let def = vec![1; v.len()];
                col.typed::<FloatType>()
                    .write_batch(&v, Some(&def), None)
                    .map_err(pq(path))?;
            }
            Column::Ints(v) => {
                let def = vec![1; v.len()];
                col.typed::<Int64Type>()
                    .write_batch(&v, Some(&def), None)
                    .map_err(pq(path))?;
            }
            Column::Text(v) => {
                let def = vec![1; v.len()];
                let v: Vec<ByteArray> = v
                    .into_iter()
                    .map(|s| ByteArray::from(s.into_bytes()))
                    .collect();
                col.typed::<ByteArrayType>()
                    .write_batch(&v, Some(&def), None)
                    .map_err(pq(path))?;
            }
        }
        col.close().map_err(pq(path))?;
    }
    rg.close().map_err(pq(path))?;
    Ok(())
}

fn write_frames(
    path: &Path,
    spec: &NewDataset,
    episodes: &[NewEpisode],
    task_of: &dyn Fn(&NewEpisode) -> i64,
) -> Result<(), LeRobotError> {
    let mut fields = Vec::new();
    for f in &spec.features {
        fields.push(list_of(&f.name, float_element().map_err(pq(path))?).map_err(pq(path))?);
    }
    fields.push(scalar("timestamp", Physical::FLOAT).map_err(pq(path))?);
    for key in BOOKKEEPING {
        fields.push(scalar(key, Physical::INT64).map_err(pq(path))?);
    }
    // The features as Hugging Face `datasets` describes them, as LeRobot's files carry.
    let mut hf = Map::new();
    for f in &spec.features {
        hf.insert(
            f.name.clone(),
            json!({"feature": {"dtype": "float32", "_type": "Value"}, "length": f.names.len(), "_type": "List"}),
        );
    }
    hf.insert(
        "timestamp".into(),
        json!({"dtype": "float32", "_type": "Value"}),
    );
    for key in BOOKKEEPING {
        hf.insert(key.into(), json!({"dtype": "int64", "_type": "Value"}));
    }
    let meta = vec![KeyValue::new(
        "huggingface".into(),
        json!({"info": {"features": hf}}).to_string(),
    )];
    let mut writer = new_file(path, fields, meta)?;
    let mut index = 0i64;
    for (e, ep) in episodes.iter().enumerate() {
        let n = ep.len();
        let mut columns: Vec<Column> = ep
            .values
            .iter()
            .map(|rows| {
                Column::Lists(
                    rows.iter()
                        .map(|r| r.iter().map(|v| *v as f32).collect())
                        .collect(),
                )
            })
            .collect();
        columns.push(Column::Floats(
            (0..n)
                .map(|k| (k as f64 / f64::from(spec.fps)) as f32)
                .collect(),
        ));
        columns.push(Column::Ints((0..n as i64).collect()));
        columns.push(Column::Ints(vec![e as i64; n]));
        columns.push(Column::Ints((index..index + n as i64).collect()));
        columns.push(Column::Ints(vec![task_of(ep); n]));
        index += n as i64;
        row_group(&mut writer, path, columns)?;
    }
    writer.close().map_err(pq(path))?;
    Ok(())
}

fn write_episodes(path: &Path, episodes: &[NewEpisode]) -> Result<(), LeRobotError> {
    let ints = [
        "length",
        "data/chunk_index",
        "data/file_index",
        "dataset_from_index",
        "dataset_to_index",
        "meta/episodes/chunk_index",
        "meta/episodes/file_index",
    ];
    let mut fields = vec![scalar("episode_index", Physical::INT64).map_err(pq(path))?];
    fields.push(list_of("tasks", text("element").map_err(pq(path))?).map_err(pq(path))?);
    for key in ints {
        fields.push(scalar(key, Physical::INT64).map_err(pq(path))?);
    }
    let mut writer = new_file(path, fields, Vec::new())?;
    let mut from = Vec::new();
    let mut at = 0i64;
    for ep in episodes {
        from.push(at);
        at += ep.len() as i64;
    }
    let n = episodes.len();
    let lengths: Vec<i64> = episodes.iter().map(|e| e.len() as i64).collect();
    let columns = vec![
        Column::Ints((0..n as i64).collect()),
        Column::Texts(episodes.iter().map(|e| vec![e.task.clone()]).collect()),
        Column::Ints(lengths.clone()),
        Column::Ints(vec![0; n]),
        Column::Ints(vec![0; n]),
        Column::Ints(from.clone()),
        Column::Ints(from.iter().zip(&lengths).map(|(f, l)| f + l).collect()),
        Column::Ints(vec![0; n]),
        Column::Ints(vec![0; n]),
    ];
    row_group(&mut writer, path, columns)?;
    writer.close().map_err(pq(path))?;
    Ok(())
}

/// `meta/tasks.parquet`: `task_index` and `task`, with pandas' note that `task` is the
/// frame's index (LeRobot reads it with `pandas.read_parquet`, indexed by task).
fn write_tasks(path: &Path, tasks: &[String]) -> Result<(), LeRobotError> {
    let fields = vec![
        scalar("task_index", Physical::INT64).map_err(pq(path))?,
        text("task").map_err(pq(path))?,
    ];
    let pandas = json!({
        "index_columns": ["task"],
        "column_indexes": [{"name": null, "field_name": null, "pandas_type": "unicode", "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64", "metadata": null},
            {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": null}
        ],
        "attributes": {},
        "creator": {"library": "cps", "version": env!("CARGO_PKG_VERSION")},
    });
    let mut writer = new_file(
        path,
        fields,
        vec![KeyValue::new("pandas".into(), pandas.to_string())],
    )?;
    row_group(
        &mut writer,
        path,
        vec![
            Column::Ints((0..tasks.len() as i64).collect()),
            Column::Text(tasks.to_vec()),
        ],
    )?;
    writer.close().map_err(pq(path))?;
    Ok(())
}

/// `meta/stats.json`: per feature and entry, min, max, mean, standard deviation, count and
/// the 1st, 10th, 50th, 90th and 99th percentiles over every frame.
fn statistics(
    spec: &NewDataset,
    episodes: &[NewEpisode],
    task_of: &dyn Fn(&NewEpisode) -> i64,
) -> Value {
    let mut out = Map::new();
    let mut add = |name: &str, columns: Vec<Vec<f64>>| {
        out.insert(name.to_string(), stats_of(columns));
    };
    for (f, feature) in spec.features.iter().enumerate() {
        let columns = (0..feature.names.len())
            .map(|j| {
                episodes
                    .iter()
                    .flat_map(|e| e.values[f].iter().map(move |r| r[j]))
                    .collect()
            })
            .collect();
        add(&feature.name, columns);
    }
    let fps = f64::from(spec.fps);
    add(
        "timestamp",
        vec![
            episodes
                .iter()
                .flat_map(|e| (0..e.len()).map(move |k| k as f64 / fps))
                .collect(),
        ],
    );
    add(
        "frame_index",
        vec![
            episodes
                .iter()
                .flat_map(|e| (0..e.len()).map(|k| k as f64))
                .collect(),
        ],
    );
    add(
        "episode_index",
        vec![
            episodes
                .iter()
                .enumerate()
                .flat_map(|(i, e)| std::iter::repeat_n(i as f64, e.len()))
                .collect(),
        ],
    );
    let total: usize = episodes.iter().map(NewEpisode::len).sum();
    add("index", vec![(0..total).map(|k| k as f64).collect()]);
    add(
        "task_index",
        vec![
            episodes
                .iter()
                .flat_map(|e| std::iter::repeat_n(task_of(e) as f64, e.len()))
                .collect(),
        ],
    );
    Value::Object(out)
}

fn stats_of(columns: Vec<Vec<f64>>) -> Value {
    let mut s: Map<String, Value> = Map::new();
    let per = |f: &dyn Fn(&[f64]) -> f64| -> Value {
        json!(columns.iter().map(|c| f(c)).collect::<Vec<f64>>())
    };
    s.insert(
        "min".into(),
        per(&|c| c.iter().copied().fold(f64::INFINITY, f64::min)),
    );
    s.insert(
        "max".into(),
        per(&|c| c.iter().copied().fold(f64::NEG_INFINITY, f64::max)),
    );
    let mean = |c: &[f64]| c.iter().sum::<f64>() / c.len() as f64;
    s.insert("mean".into(), per(&mean));
    s.insert(
        "std".into(),
        per(&|c| {
            let m = mean(c);
            (c.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / c.len() as f64).sqrt()
        }),
    );
    s.insert("count".into(), json!([columns.first().map_or(0, Vec::len)]));
    for (key, q) in [
        ("q01", 0.01),
        ("q10", 0.10),
        ("q50", 0.50),
        ("q90", 0.90),
        ("q99", 0.99),
    ] {
        s.insert(key.into(), per(&|c| quantile(c, q)));
    }
    Value::Object(s)
}

/// The `q` quantile of `values`, linear between order statistics.
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let x = q * (v.len() - 1) as f64;
    let (lo, hi) = (x.floor() as usize, x.ceil() as usize);
    v[lo] + (v[hi] - v[lo]) * (x - lo as f64)
}
