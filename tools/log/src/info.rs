//! `info`: what a log holds and how damaged it is.

use std::collections::BTreeMap;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use skyframe_core::logfmt::{Event, LogReader, Problem, ProblemKind, Record, Time};

use crate::Outcome;
use crate::input::{problem_line, progress_bar, read_file, report_line};

/// Most problems and Begin/End markers listed per file (all are counted; every problem is
/// also on stderr), so a badly damaged file keeps the summary readable and memory bounded.
const MAX_LISTED: usize = 1000;

pub fn run(files: &[PathBuf], gap_s: f64) -> Outcome {
    // Seconds to whole ns; NaN or negative: every step is a gap (0), huge: none.
    let gap_ns = if gap_s.is_nan() { 0.0 } else { gap_s * 1e9 }.clamp(0.0, 1e30) as i128;
    let bar = progress_bar(files);
    let mut reader = Box::new(LogReader::new());
    let mut outcome = Outcome::Whole;
    let stdout = io::stdout();
    for (n, file) in files.iter().enumerate() {
        bar.set_message(file.display().to_string());
        let mut summary = Summary {
            gap_ns,
            ..Summary::default()
        };
        let read = read_file(file, &mut reader, &bar, |event| {
            if let Event::Problem(problem) = &event {
                report_line(&bar, &problem_line(file, problem));
            }
            summary.add(event);
        });
        if let Err(e) = read {
            report_line(&bar, &format!("skyframe-log: {}: {e}", file.display()));
            outcome = outcome.max(Outcome::Failed);
            continue;
        }
        if summary.problem_count > 0 {
            outcome = outcome.max(Outcome::Reported);
        }
        let printed = bar.suspend(|| {
            let mut out = stdout.lock();
            if n > 0 {
                writeln!(out)?;
            }
            summary.print(&mut out, file)
        });
        if printed.is_err() {
            // stdout closed (e.g. piped into `head`): nothing more to say.
            bar.finish_and_clear();
            return outcome.max(Outcome::Failed);
        }
    }
    bar.finish_and_clear();
    outcome
}

struct Definition {
    offset: u64,
    index: u8,
    text: String,
    valid: bool,
}

#[derive(Default)]
struct Counts {
    data_blocks: u64,
    byte_arrays: u64,
}

#[derive(Default)]
struct Summary {
    definitions: Vec<Definition>,
    comments: BTreeMap<u8, String>,
    counts: BTreeMap<u8, Counts>,
    first_time: Option<Time>,
    last_time: Option<Time>,
    earliest: Option<Time>,
    latest: Option<Time>,
    /// The largest step between consecutive timed records: (ns, offset of the later).
    largest_step: Option<(i128, u64)>,
    backward_steps: u64,
    /// (is Begin, time, offset)
    markers: Vec<(bool, Time, u64)>,
    marker_count: u64,
    problems: Vec<Problem>,
    problem_count: u64,
    closed_cleanly: bool,
    /// Steps longer than this between records of one format are gaps.
    gap_ns: i128,
    /// Per format index, its last data record: (time, offset).
    last_of_format: BTreeMap<u8, (Time, u64)>,
    /// (index, length ns, offset before, offset after)
    gaps: Vec<(u8, i128, u64, u64)>,
    gap_count: u64,
}

fn ns(time: Time) -> i128 {
    i128::from(time.sec) * 1_000_000_000 + i128::from(time.nsec)
}

/// A signed duration in seconds with nine decimals.
fn seconds(ns: i128) -> String {
    let sign = if ns < 0 { "-" } else { "" };
    let ns = ns.unsigned_abs();
    format!("{sign}{}.{:09}", ns / 1_000_000_000, ns % 1_000_000_000)
}

impl Summary {
    fn add(&mut self, event: Event<'_>) {
        match event {
            Event::Problem(problem) => {
                self.problem_count += 1;
                if self.problems.len() < MAX_LISTED {
                    self.problems.push(problem);
                }
            }
            Event::Record { offset, record } => {
                self.closed_cleanly = matches!(record, Record::EndData { .. });
                let time = match record {
                    Record::BeginData { time } | Record::EndData { time } => {
                        self.marker_count += 1;
                        if self.markers.len() < MAX_LISTED {
                            let begin = matches!(record, Record::BeginData { .. });
                            self.markers.push((begin, time, offset));
                        }
                        Some(time)
                    }
                    Record::FormatDefinition {
                        index,
                        text,
                        format,
                    } => {
                        if self.definitions.len() < MAX_LISTED {
                            self.definitions.push(Definition {
                                offset,
                                index,
                                text: String::from_utf8_lossy(text).into_owned(),
                                valid: format.is_some(),
                            });
                        }
                        None
                    }
                    Record::FormatComment { index, text } => {
                        self.comments
                            .insert(index, String::from_utf8_lossy(text).into_owned());
                        None
                    }
                    Record::DataBlock { index, time, .. } => {
                        self.counts.entry(index).or_default().data_blocks += 1;
                        self.add_data_time(index, time, offset);
                        Some(time)
                    }
                    Record::ByteArray { index, time, .. } => {
                        self.counts.entry(index).or_default().byte_arrays += 1;
                        self.add_data_time(index, time, offset);
                        Some(time)
                    }
                };
                if let Some(time) = time {
                    self.add_time(time, offset);
                }
            }
        }
    }

    fn add_data_time(&mut self, index: u8, time: Time, offset: u64) {
        if let Some((last, last_offset)) = self.last_of_format.insert(index, (time, offset)) {
            let step = ns(time) - ns(last);
            if step > self.gap_ns {
                self.gap_count += 1;
                if self.gaps.len() < MAX_LISTED {
                    self.gaps.push((index, step, last_offset, offset));
                }
            }
        }
    }

    fn add_time(&mut self, time: Time, offset: u64) {
        if let Some(last) = self.last_time {
            let step = ns(time) - ns(last);
            if step < 0 {
                self.backward_steps += 1;
            }
            if self.largest_step.is_none_or(|(largest, _)| step > largest) {
                self.largest_step = Some((step, offset));
            }
        }
        self.first_time.get_or_insert(time);
        self.last_time = Some(time);
        self.earliest = Some(self.earliest.map_or(time, |t| t.min(time)));
        self.latest = Some(self.latest.map_or(time, |t| t.max(time)));
    }

    fn print(&self, out: &mut impl Write, path: &Path) -> io::Result<()> {
        let size = std::fs::metadata(path).map(|m| m.len()).ok();
        match size {
            Some(size) => writeln!(out, "{} ({size} bytes)", path.display())?,
            None => writeln!(out, "{}", path.display())?,
        }
        writeln!(out, "  formats:")?;
        if self.definitions.is_empty() {
            writeln!(out, "    none")?;
        }
        for d in &self.definitions {
            let validity = if d.valid { "" } else { "  INVALID" };
            writeln!(
                out,
                "    {} (offset {}): {}{validity}",
                d.index, d.offset, d.text
            )?;
            if let Some(columns) = self.comments.get(&d.index) {
                writeln!(out, "      columns: {columns}")?;
            }
        }
        writeln!(out, "  records per format:")?;
        if self.counts.is_empty() {
            writeln!(out, "    none")?;
        }
        for (index, counts) in &self.counts {
            write!(out, "    {index}: data blocks {}", counts.data_blocks)?;
            if counts.byte_arrays > 0 {
                write!(out, ", byte arrays {}", counts.byte_arrays)?;
            }
            writeln!(out)?;
        }
        match (self.earliest, self.latest) {
            (Some(earliest), Some(latest)) => writeln!(
                out,
                "  time span: {earliest} to {latest} ({} s)",
                seconds(ns(latest) - ns(earliest))
            )?,
            _ => writeln!(out, "  time span: no timed records")?,
        }
        if let Some((step, offset)) = self.largest_step {
            writeln!(
                out,
                "  largest time step: {} s, to the record at offset {offset}",
                seconds(step)
            )?;
        }
        if self.backward_steps > 0 {
            writeln!(out, "  time went backwards {} times", self.backward_steps)?;
        }
        if self.gap_count == 0 {
            writeln!(out, "  gaps: none")?;
        } else {
            writeln!(out, "  gaps: {}", self.gap_count)?;
            for &(index, step, before, after) in &self.gaps {
                writeln!(
                    out,
                    "    format {index}: {} s between offsets {before} and {after}",
                    seconds(step)
                )?;
            }
            if self.gap_count > self.gaps.len() as u64 {
                writeln!(
                    out,
                    "    ... {} more gaps",
                    self.gap_count - self.gaps.len() as u64
                )?;
            }
        }
        self.print_pairs(out)?;
        writeln!(
            out,
            "  closed cleanly: {}",
            if self.closed_cleanly {
                "yes"
            } else {
                "no (no final End Data)"
            }
        )?;
        let damage: Vec<&Problem> = self
            .problems
            .iter()
            .filter(|p| p.kind != ProblemKind::NotClosedCleanly)
            .collect();
        if damage.is_empty() {
            writeln!(out, "  damage: none")?;
        } else {
            let skipped: u64 = damage
                .iter()
                .map(|p| p.resume_offset.saturating_sub(p.offset))
                .sum();
            writeln!(
                out,
                "  damage: problems {}, bytes skipped {skipped}",
                damage.len()
            )?;
            for p in &damage {
                writeln!(
                    out,
                    "    offset {}..{}: {}",
                    p.offset, p.resume_offset, p.kind
                )?;
            }
            if self.problem_count > self.problems.len() as u64 {
                writeln!(
                    out,
                    "    ... {} more problems (all on stderr)",
                    self.problem_count - self.problems.len() as u64
                )?;
            }
        }
        Ok(())
    }

    /// Begin/End pairs in file order: each Begin with the next End.
    fn print_pairs(&self, out: &mut impl Write) -> io::Result<()> {
        writeln!(out, "  Begin/End pairs:")?;
        if self.markers.is_empty() {
            writeln!(out, "    none")?;
        }
        let mut open: Option<(Time, u64)> = None;
        for &(begin, time, offset) in &self.markers {
            match (begin, open) {
                (true, Some((t, o))) => {
                    writeln!(out, "    begin {t} (offset {o}) without End Data")?;
                    open = Some((time, offset));
                }
                (true, None) => open = Some((time, offset)),
                (false, Some((t, o))) => {
                    writeln!(
                        out,
                        "    begin {t} (offset {o}) to end {time} (offset {offset}): {} s",
                        seconds(ns(time) - ns(t))
                    )?;
                    open = None;
                }
                (false, None) => {
                    writeln!(out, "    end {time} (offset {offset}) without Begin Data")?
                }
            }
        }
        if let Some((t, o)) = open {
            writeln!(out, "    begin {t} (offset {o}) without End Data")?;
        }
        if self.marker_count > self.markers.len() as u64 {
            writeln!(
                out,
                "    ... {} more markers",
                self.marker_count - self.markers.len() as u64
            )?;
        }
        Ok(())
    }
}
