//! Rewrites a Parquet fleet as an Arrow IPC file or stream of ONE record batch, the layout
//! that costs a reader decoding whole batches the whole batch in memory (issue 26; pandas'
//! `to_feather` and many exporters write a table as one batch). Used by
//! `scripts/fleet-memory.sh`; it holds the whole table in memory itself.
//!
//! `cargo run --release -p rootfuse-columnar --example one_batch -- IN.parquet OUT.arrow [--stream]`
use arrow::record_batch::{RecordBatchReader, RecordBatchWriter};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(input), Some(output)) = (args.first(), args.get(1)) else {
        return Err("usage: one_batch IN.parquet OUT.arrow [--stream]".into());
    };
    let stream = args.iter().any(|a| a == "--stream");
    let reader = ParquetRecordBatchReaderBuilder::try_new(std::fs::File::open(input)?)?
        .with_batch_size(1 << 20)
        .build()?;
    let schema = reader.schema();
    let batches = reader.collect::<Result<Vec<_>, _>>()?;
    let batch = arrow::compute::concat_batches(&schema, &batches)?;
    drop(batches);
    let file = std::io::BufWriter::new(std::fs::File::create(output)?);
    fn write(
        mut w: impl RecordBatchWriter,
        batch: &arrow::record_batch::RecordBatch,
    ) -> Result<(), arrow::error::ArrowError> {
        w.write(batch)?;
        w.close()
    }
    if stream {
        write(
            arrow::ipc::writer::StreamWriter::try_new(file, &schema)?,
            &batch,
        )?;
    } else {
        write(
            arrow::ipc::writer::FileWriter::try_new(file, &schema)?,
            &batch,
        )?;
    }
    println!("{} rows in one record batch: {output}", batch.num_rows());
    Ok(())
}
