//! Where in a scenario file an error is: line and column of a byte offset, the key inside a
//! table, and the one-line messages of the checks every value goes through.

use super::ScenarioError;
use std::ops::Range;

pub(super) use skyframe_core::schedule::file::line_column;

/// The text a table's keys are in: for an inline table its span; for a `[header]` table (whose
/// span is the header alone) from the header to the next header or the end.
pub(super) fn table_region(src: &str, span: &Range<usize>) -> Range<usize> {
    let header = src.get(span.clone()).unwrap_or("");
    if !header.trim_start().starts_with('[') {
        return span.clone();
    }
    let body_start = span.end.min(src.len());
    let rest = src.get(body_start..).unwrap_or("");
    let mut offset = body_start;
    for line in rest.split_inclusive('\n') {
        if offset > body_start && line.trim_start().starts_with('[') {
            return span.start..offset;
        }
        offset += line.len();
    }
    span.start..src.len()
}

/// Where `key = ...` is written in the table at `span`, or the start of `span` if it is not
/// found.
pub(super) fn key_offset(src: &str, span: &Range<usize>, key: &str) -> usize {
    let region = table_region(src, span);
    let Some(text) = src.get(region.clone()) else {
        return span.start;
    };
    let bytes = text.as_bytes();
    let mut from = 0;
    while let Some(found) = text.get(from..).and_then(|t| t.find(key)) {
        let at = from + found;
        let before_ok =
            at == 0 || !matches!(bytes[at - 1], b'a'..=b'z' | b'A'..=b'Z' | b'0'..=b'9' | b'_');
        let rest = text.get(at + key.len()..).unwrap_or("");
        let after_ok = rest.trim_start_matches([' ', '\t']).starts_with('=');
        if before_ok && after_ok {
            return region.start + at;
        }
        from = at + key.len();
    }
    span.start
}

/// The key whose value starts at `offset` (`key = value` on one line), if any.
pub(super) fn key_before(src: &str, offset: usize) -> Option<&str> {
    let before = src.get(..offset)?;
    let line = before.rsplit('\n').next()?;
    let assignment = line.rfind('=')?;
    let name = line.get(..assignment)?.trim_end();
    let start = name
        .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .map_or(0, |i| i + 1);
    let key = name.get(start..)?;
    (!key.is_empty()).then_some(key)
}

pub(super) struct Locator<'a> {
    pub(super) src: &'a str,
}

impl Locator<'_> {
    pub(super) fn at(&self, offset: usize, message: String) -> ScenarioError {
        let (line, column) = line_column(self.src, offset);
        ScenarioError {
            line,
            column,
            message,
        }
    }

    pub(super) fn key(&self, span: &Range<usize>, key: &str, message: String) -> ScenarioError {
        self.at(key_offset(self.src, span, key), message)
    }

    pub(super) fn line_of(&self, span: &Range<usize>) -> usize {
        line_column(self.src, span.start).0
    }
}

pub(super) fn finite(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    key: &str,
    value: f64,
) -> Result<f64, ScenarioError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(loc.key(
            span,
            key,
            format!("{what}: `{key}` must be a finite number"),
        ))
    }
}

#[allow(clippy::too_many_arguments)]
pub(super) fn in_range(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    key: &str,
    value: f64,
    low: f64,
    high: f64,
) -> Result<f64, ScenarioError> {
    if value.is_finite() && (low..=high).contains(&value) {
        Ok(value)
    } else {
        Err(loc.key(
            span,
            key,
            format!("{what}: `{key}` = {value} is outside {low}..={high}"),
        ))
    }
}

pub(super) fn one_of<T: Copy>(
    loc: &Locator,
    span: &Range<usize>,
    what: &str,
    key: &str,
    value: &str,
    choices: &[(&str, T)],
) -> Result<T, ScenarioError> {
    choices
        .iter()
        .find(|(name, _)| *name == value)
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            let names: Vec<String> = choices.iter().map(|(n, _)| format!("\"{n}\"")).collect();
            loc.key(
                span,
                key,
                format!(
                    "{what}: unknown {key} \"{value}\", expected one of {}",
                    names.join(", ")
                ),
            )
        })
}
