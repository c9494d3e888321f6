//! `skyframe-horizon`: the horizon detector of `skyframe_core::horizon` on video files, the
//! synthetic flights it is tested on, and the benchmark against an OpenCV pipeline.

pub mod accuracy;
pub mod bench;
pub mod camera_file;
pub mod detect;
pub mod image_io;
pub mod send;
pub mod synth;
pub mod terrain;

/// A failure the tool reports in one line. `Input` (exit 2): the input, a file or an argument
/// is wrong; `Failure` (exit 1): something else went wrong (an external program, a write).
#[derive(Debug)]
pub enum Error {
    Input(String),
    Failure(String),
}

impl Error {
    pub fn input(message: impl Into<String>) -> Self {
        Error::Input(message.into())
    }

    pub fn failure(message: impl Into<String>) -> Self {
        Error::Failure(message.into())
    }

    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input(_) => 2,
            Error::Failure(_) => 1,
        }
    }
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (Error::Input(m) | Error::Failure(m)) = self;
        // One line, whatever a library put in its message.
        write!(f, "{}", m.replace('\n', " "))
    }
}
