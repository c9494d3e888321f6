//! A flight's streams loaded into columns, for `plot`: every data block's fields as `f64`,
//! every record's time, per stream and format index (`docs/log-streams.md`).

use std::path::{Path, PathBuf};

pub use skyframe_logtable::{Stream, Table, stream_name};

use crate::input::problem_line;

/// Reads a stream file into its tables; reader problems are printed on stderr (as `info`
/// does) and counted; only I/O errors fail.
pub fn load_stream(path: &Path) -> Result<Stream, String> {
    skyframe_logtable::load_stream(path, |problem| eprintln!("{}", problem_line(path, problem)))
}

/// Where a flight's streams are: a directory of `<stream>.bin`, or one `.bin` file.
pub enum Source {
    Dir(PathBuf),
    File(PathBuf),
}

impl Source {
    pub fn new(path: &Path) -> Result<Source, String> {
        if path.is_dir() {
            Ok(Source::Dir(path.to_path_buf()))
        } else if path.is_file() {
            Ok(Source::File(path.to_path_buf()))
        } else {
            Err(format!("{}: no such file or directory", path.display()))
        }
    }

    /// The names of the streams there, sorted.
    pub fn stream_names(&self) -> Vec<String> {
        match self {
            Source::File(path) => vec![stream_name(path)],
            Source::Dir(dir) => {
                let mut names: Vec<String> = std::fs::read_dir(dir)
                    .into_iter()
                    .flatten()
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "bin"))
                    .map(|p| stream_name(&p))
                    .filter(|n| !n.starts_with('.'))
                    .collect();
                names.sort();
                names
            }
        }
    }

    /// The file of stream `name`, if the source has it.
    pub fn stream_path(&self, name: &str) -> Option<PathBuf> {
        match self {
            Source::File(path) => (stream_name(path) == name).then(|| path.clone()),
            Source::Dir(dir) => {
                let path = dir.join(format!("{name}.bin"));
                path.is_file().then_some(path)
            }
        }
    }

    /// Why stream `name` is not there, for a note.
    pub fn missing(&self, name: &str) -> String {
        match self {
            Source::Dir(dir) => format!("no {name}.bin in {}", dir.display()),
            Source::File(path) => format!(
                "no {name} stream: {} is the {} stream (give the flight directory)",
                path.display(),
                stream_name(path)
            ),
        }
    }

    pub fn display(&self) -> String {
        match self {
            Source::Dir(p) | Source::File(p) => p.display().to_string(),
        }
    }
}
