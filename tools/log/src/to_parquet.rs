//! `to-parquet`: many flights as Parquet, for pandas/pyarrow/DuckDB across flights.
//!
//! One file per stream and format, `<stream>.<index>.parquet`, with one row group per
//! flight. Columns: `flight_id` and `vehicle_id` (strings), `time_ns` (the log TIME in ns,
//! INT64), then the format's columns typed as logged: f32 → FLOAT, f64 → DOUBLE, integers
//! as Parquet integers with their logical width and signedness (u8 → INT32 annotated
//! INTEGER(8, false), …), so a reader gets `uint8`, `float32`, … back. Values are the log's
//! bits, not rounded through text.
//!
//! A flight whose format has a different layout (columns or types) from the one already in
//! the file goes to `<stream>.<index>-<n>.parquet` instead, with a note: a Parquet file has
//! one schema.

use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, FloatType, Int32Type, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::parser::parse_message_type;
use skyframe_core::logfmt::{FieldType, Value};

use crate::Outcome;
use crate::flightlog::{Flight, Layout, stream_files};

/// A field's Parquet physical type and logical annotation.
fn parquet_type(ty: FieldType) -> (&'static str, &'static str) {
    match ty {
        FieldType::I8 => ("INT32", " (INTEGER(8,true))"),
        FieldType::U8 => ("INT32", " (INTEGER(8,false))"),
        FieldType::I16 => ("INT32", " (INTEGER(16,true))"),
        FieldType::U16 => ("INT32", " (INTEGER(16,false))"),
        FieldType::I32 => ("INT32", " (INTEGER(32,true))"),
        FieldType::U32 => ("INT32", " (INTEGER(32,false))"),
        FieldType::I64 => ("INT64", " (INTEGER(64,true))"),
        FieldType::U64 => ("INT64", " (INTEGER(64,false))"),
        FieldType::F32 => ("FLOAT", ""),
        FieldType::F64 => ("DOUBLE", ""),
    }
}

/// Column names made Parquet/SQL-friendly identifiers, unique, never one of ours.
fn column_names(layout: &Layout) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for (i, column) in layout.columns.iter().enumerate() {
        let mut name = crate::flightlog::identifier(column.trim(), "c");
        if ["flight_id", "vehicle_id", "time_ns"].contains(&name.as_str()) {
            name = format!("{name}_log");
        }
        if names.contains(&name) {
            name = format!("{name}_{i}");
        }
        names.push(name);
    }
    names
}

fn schema(layout: &Layout) -> String {
    let mut text = String::from(
        "message skyframe {\n  REQUIRED BYTE_ARRAY flight_id (STRING);\n  \
         REQUIRED BYTE_ARRAY vehicle_id (STRING);\n  REQUIRED INT64 time_ns;\n",
    );
    for (ty, name) in layout.types().zip(column_names(layout)) {
        let (physical, logical) = parquet_type(ty);
        text.push_str(&format!("  REQUIRED {physical} {name}{logical};\n"));
    }
    text.push('}');
    text
}

struct Output {
    path: PathBuf,
    schema: String,
    writer: SerializedFileWriter<File>,
}

pub fn run(inputs: &[PathBuf], out_dir: &Path, vehicle_id: Option<&str>) -> Outcome {
    Outcome::of_conversion(convert(inputs, out_dir, vehicle_id))
}

/// Converts every flight; returns the lines to report: the logs' damage, and notes.
fn convert(
    inputs: &[PathBuf],
    out_dir: &Path,
    vehicle_id: Option<&str>,
) -> Result<Vec<String>, String> {
    if inputs.is_empty() {
        return Err("to-parquet: no flight directories given".into());
    }
    // Every input is checked before anything is written.
    let mut flights = Vec::new();
    for input in inputs {
        flights.push((input, stream_files(input)?));
    }
    std::fs::create_dir_all(out_dir)
        .map_err(|e| format!("{}: cannot create directory: {e}", out_dir.display()))?;
    let vehicle_id = vehicle_id.unwrap_or("unknown");
    let mut outputs: BTreeMap<(String, u8), Vec<Output>> = BTreeMap::new();
    let mut lines = Vec::new();
    let mut rows = 0usize;
    for (input, files) in flights {
        let flight = Flight::load(&files)?;
        lines.extend(flight.damage.iter().map(|d| d.line.clone()));
        let flight_id = crate::to_ulog::flight_id(input);
        // Layouts of one stream and index with the same schema share a row group.
        let mut groups: BTreeMap<(String, u8, String), Vec<usize>> = BTreeMap::new();
        for (l, layout) in flight.layouts.iter().enumerate() {
            groups
                .entry((layout.stream.clone(), layout.index, schema(layout)))
                .or_default()
                .push(l);
        }
        for ((stream, index, schema_text), layouts) in groups {
            let files = outputs.entry((stream.clone(), index)).or_default();
            let slot = match files.iter().position(|o| o.schema == schema_text) {
                Some(slot) => slot,
                None => {
                    let name = match files.len() {
                        0 => format!("{stream}.{index}.parquet"),
                        n => format!("{stream}.{index}-{}.parquet", n + 1),
                    };
                    let path = out_dir.join(name);
                    if !files.is_empty() {
                        lines.push(format!(
                            "skyframe-log: note: {}: {stream}.bin format {index} has another \
                             layout than in earlier flights: written to {}",
                            input.display(),
                            path.display()
                        ));
                    }
                    files.push(open(&path, &schema_text)?);
                    files.len() - 1
                }
            };
            let Some(output) = files.get_mut(slot) else {
                continue;
            };
            rows += write_row_group(output, &flight, &layouts, &flight_id, vehicle_id)
                .map_err(|e| format!("{}: {e}", output.path.display()))?;
        }
    }
    if rows == 0 {
        return Err(format!(
            "no data records to convert in {}",
            inputs
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    for (_, files) in outputs {
        for output in files {
            output
                .writer
                .close()
                .map_err(|e| format!("{}: {e}", output.path.display()))?;
        }
    }
    Ok(lines)
}

fn open(path: &Path, schema_text: &str) -> Result<Output, String> {
    let err = |e: String| format!("{}: {e}", path.display());
    let schema = parse_message_type(schema_text).map_err(|e| err(e.to_string()))?;
    let file = File::create(path).map_err(|e| err(e.to_string()))?;
    let properties = Arc::new(WriterProperties::builder().build());
    let writer = SerializedFileWriter::new(file, Arc::new(schema), properties)
        .map_err(|e| err(e.to_string()))?;
    Ok(Output {
        path: path.to_path_buf(),
        schema: schema_text.to_string(),
        writer,
    })
}

/// Writes one flight's records of `layouts` (one schema) as one row group; returns the rows.
fn write_row_group(
    output: &mut Output,
    flight: &Flight,
    layouts: &[usize],
    flight_id: &str,
    vehicle_id: &str,
) -> Result<usize, parquet::errors::ParquetError> {
    let records: Vec<_> = flight
        .records
        .iter()
        .filter(|r| layouts.contains(&r.layout))
        .collect();
    let Some(first) = layouts.first().and_then(|&l| flight.layouts.get(l)) else {
        return Ok(0);
    };
    let types: Vec<FieldType> = first.types().collect();
    let offsets: Vec<usize> = types
        .iter()
        .scan(0, |offset, ty| {
            let at = *offset;
            *offset += ty.size();
            Some(at)
        })
        .collect();
    let mut group = output.writer.next_row_group()?;
    let mut column = 0usize;
    while let Some(mut writer) = group.next_column()? {
        match column {
            0 | 1 => {
                let text = if column == 0 { flight_id } else { vehicle_id };
                let values = vec![ByteArray::from(text); records.len()];
                writer
                    .typed::<ByteArrayType>()
                    .write_batch(&values, None, None)?;
            }
            2 => {
                let values: Vec<i64> = records.iter().map(|r| r.t_ns).collect();
                writer
                    .typed::<Int64Type>()
                    .write_batch(&values, None, None)?;
            }
            c => {
                let f = c - 3;
                let (Some(&ty), Some(&offset)) = (types.get(f), offsets.get(f)) else {
                    writer.close()?;
                    column += 1;
                    continue;
                };
                let value = |r: &&crate::flightlog::Rec| {
                    flight
                        .bytes(r)
                        .get(offset..)
                        .and_then(|b| Value::decode(ty, b))
                };
                match ty {
                    FieldType::F32 => {
                        let v: Vec<f32> = records
                            .iter()
                            .map(|r| match value(r) {
                                Some(Value::F32(x)) => x,
                                _ => f32::NAN,
                            })
                            .collect();
                        writer.typed::<FloatType>().write_batch(&v, None, None)?;
                    }
                    FieldType::F64 => {
                        let v: Vec<f64> = records
                            .iter()
                            .map(|r| match value(r) {
                                Some(Value::F64(x)) => x,
                                _ => f64::NAN,
                            })
                            .collect();
                        writer.typed::<DoubleType>().write_batch(&v, None, None)?;
                    }
                    FieldType::I64 | FieldType::U64 => {
                        // u64 keeps its bits in INT64; the UINT_64 annotation reads it back.
                        let v: Vec<i64> = records
                            .iter()
                            .map(|r| match value(r) {
                                Some(Value::I64(x)) => x,
                                Some(Value::U64(x)) => x as i64,
                                _ => 0,
                            })
                            .collect();
                        writer.typed::<Int64Type>().write_batch(&v, None, None)?;
                    }
                    _ => {
                        // Narrow integers widen into INT32; u32 keeps its bits (UINT_32).
                        let v: Vec<i32> = records
                            .iter()
                            .map(|r| match value(r) {
                                Some(Value::I8(x)) => i32::from(x),
                                Some(Value::U8(x)) => i32::from(x),
                                Some(Value::I16(x)) => i32::from(x),
                                Some(Value::U16(x)) => i32::from(x),
                                Some(Value::I32(x)) => x,
                                Some(Value::U32(x)) => x as i32,
                                _ => 0,
                            })
                            .collect();
                        writer.typed::<Int32Type>().write_batch(&v, None, None)?;
                    }
                }
            }
        }
        writer.close()?;
        column += 1;
    }
    group.close()?;
    Ok(records.len())
}
