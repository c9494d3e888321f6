//! `skyframe-horizon`: roll and pitch from video, synthetic test flights, and the benchmark.

use clap::{Parser, Subcommand, ValueEnum};
use skyframe_horizon::camera_file::{self, CameraFile};
use skyframe_horizon::detect::{self, CSV_HEADER, Runner, Source};
use skyframe_horizon::image_io::{self, Y4mWriter};
use skyframe_horizon::send::{SendArgs, Sender};
use skyframe_horizon::synth::{Degradation, Renderer, TRUTH_HEADER, truth_line};
use skyframe_horizon::terrain::{Class, TerrainRenderer};
use skyframe_horizon::{Error, bench};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "skyframe-horizon",
    version,
    about = "Horizon detection: roll and pitch from a forward camera's video",
    long_about = "Horizon detection: roll and pitch from a forward camera's video.\n\n\
        Angles follow the skyframe conventions (roll positive right wing down, pitch positive \
        nose up). Exit codes: 0 success, 2 bad input (file, format, argument; one line on \
        stderr naming the file and byte offset where it applies), 1 other failures."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Detect the horizon in every frame; CSV `frame,roll_deg,pitch_deg,confidence,ms`.
    ///
    /// INPUT is a YUV4MPEG2 stream (a file, or `-` for stdin, e.g.
    /// `ffmpeg -i flight.mp4 -f yuv4mpegpipe - | skyframe-horizon detect -`), a directory of
    /// PNG/PGM/PPM frames (taken in file-name order, numbered from 0), or a single image.
    /// A frame without a horizon has empty roll and pitch.
    Detect {
        /// y4m file, `-` (stdin), directory of frames, or one image.
        input: PathBuf,
        /// Camera file (TOML, conventions). Without it: 60° horizontal field of view, no
        /// distortion, principal point at the centre.
        #[arg(long)]
        camera: Option<PathBuf>,
        /// Write the CSV here instead of stdout.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Write each frame as PNG with the detected line drawn (green: confidence ≥ 0.5,
        /// orange below; a tick points to the ground side) into this directory.
        #[arg(long)]
        annotate: Option<PathBuf>,
        /// Print each frame's outcome (why no horizon) and edge count on stderr.
        #[arg(long)]
        verbose: bool,
        #[command(flatten)]
        send: SendArgs,
    },
    /// Render a synthetic flight with ground truth: frames, `truth.csv`
    /// (`frame,roll_deg,pitch_deg`) and `camera.toml` in DIR.
    Synth {
        /// Output directory (created if missing).
        #[arg(long = "out")]
        out: PathBuf,
        /// Degradation of the seed's flight video to add.
        #[arg(long, value_enum, default_value = "clean")]
        degradation: Degradation,
        #[arg(long, default_value_t = 100)]
        frames: usize,
        #[arg(long, default_value_t = 320)]
        width: usize,
        #[arg(long, default_value_t = 240)]
        height: usize,
        /// The same seed gives the same frames, byte for byte.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// png/pgm: one file per frame (`frame_000000.png`); y4m: one `frames.y4m` stream.
        #[arg(long, value_enum, default_value = "png")]
        format: SynthFormat,
        /// Render with the second generator (`terrain`) instead, this class of it
        /// (--degradation is then ignored).
        #[arg(long, value_enum)]
        terrain: Option<Class>,
    },
    /// Speed and accuracy of this detector and of an OpenCV pipeline on the same synthetic
    /// frames (needs `python3` with opencv-python-headless 4.x unless --no-opencv).
    Bench(bench::BenchArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum SynthFormat {
    Png,
    Pgm,
    Y4m,
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Detect {
            input,
            camera,
            output,
            annotate,
            verbose,
            send,
        } => run_detect(input, camera, output, annotate, verbose, &send),
        Command::Synth {
            out,
            degradation,
            frames,
            width,
            height,
            seed,
            format,
            terrain,
        } => run_synth(
            out,
            degradation,
            terrain,
            frames,
            width,
            height,
            seed,
            format,
        ),
        Command::Bench(args) => bench::run(&args),
    };
    if let Err(e) = result {
        eprintln!("skyframe-horizon: {e}");
        std::process::exit(e.exit_code());
    }
}

fn run_detect(
    input: PathBuf,
    camera: Option<PathBuf>,
    output: Option<PathBuf>,
    annotate: Option<PathBuf>,
    verbose: bool,
    send: &SendArgs,
) -> Result<(), Error> {
    let camera = camera.as_deref().map(CameraFile::load).transpose()?;
    let mut sender = Sender::open(send)?;
    if let Some(dir) = &annotate {
        std::fs::create_dir_all(dir)
            .map_err(|e| Error::input(format!("{}: {e}", dir.display())))?;
    }
    let source = Source::open(&input)?;
    let mut out = detect::csv_output(output.as_deref())?;
    let write_error = |e: std::io::Error| Error::failure(format!("writing the CSV: {e}"));
    writeln!(out, "{CSV_HEADER}").map_err(write_error)?;
    let mut runner: Option<Runner> = None;
    source.for_each(|index, image| {
        let captured = Instant::now();
        let runner = runner.get_or_insert_with(|| {
            let camera =
                camera.unwrap_or_else(|| camera_file::default_camera(image.width, image.height));
            Runner::new(camera)
        });
        let result = runner
            .run(image)
            .map_err(|m| Error::input(format!("{}: frame {index}: {m}", input.display())))?;
        writeln!(out, "{}", detect::csv_line(index, &result)).map_err(write_error)?;
        if let (Some(sender), Some(horizon)) = (&mut sender, &result.horizon) {
            sender.send(horizon, captured)?;
        }
        if verbose {
            let pattern = runner
                .detector
                .last_interference_period()
                .map(|p| format!(", a periodic pattern of {p:.1} working px notched out"))
                .unwrap_or_default();
            let coded = runner
                .detector
                .last_coded_tile()
                .map(|t| format!(", coded in {t}-px blocks"))
                .unwrap_or_default();
            eprintln!(
                "frame {index}: {:?}, {} edge points, working image binned {}x{pattern}{coded}",
                runner.detector.last_outcome(),
                runner.detector.last_edge_count(),
                runner.detector.last_working_scale()
            );
        }
        if let Some(dir) = &annotate {
            let drawn = detect::annotate(image, runner.detector.camera(), result.horizon.as_ref());
            image_io::write_png(&dir.join(format!("frame_{index:06}.png")), &drawn)?;
        }
        Ok(())
    })?;
    if let (true, Some(sender)) = (verbose, &sender) {
        eprintln!("sent {} horizon commands", sender.sent);
    }
    out.flush().map_err(write_error)
}

#[allow(clippy::too_many_arguments)]
fn run_synth(
    out: PathBuf,
    degradation: Degradation,
    terrain: Option<Class>,
    frames: usize,
    width: usize,
    height: usize,
    seed: u64,
    format: SynthFormat,
) -> Result<(), Error> {
    if !(32..=4096).contains(&width) || !(32..=4096).contains(&height) {
        return Err(Error::input(format!(
            "--width/--height {width}×{height}: each must be 32 to 4096"
        )));
    }
    let io = |path: &std::path::Path, e: std::io::Error| {
        Error::input(format!("{}: {e}", path.display()))
    };
    std::fs::create_dir_all(&out).map_err(|e| io(&out, e))?;
    enum Either {
        Synth(Renderer),
        Terrain(TerrainRenderer),
    }
    let renderer = match terrain {
        Some(class) => Either::Terrain(TerrainRenderer::new(class, width, height, seed)),
        None => Either::Synth(Renderer::new(degradation, width, height, seed)),
    };
    let camera = match &renderer {
        Either::Synth(r) => r.camera,
        Either::Terrain(r) => r.camera,
    };
    let camera_path = out.join("camera.toml");
    std::fs::write(&camera_path, CameraFile::to_toml(&camera)).map_err(|e| io(&camera_path, e))?;
    let mut truth = String::from(TRUTH_HEADER);
    let y4m_path = out.join("frames.y4m");
    let mut y4m = match format {
        SynthFormat::Y4m => {
            let file = std::fs::File::create(&y4m_path).map_err(|e| io(&y4m_path, e))?;
            Some(
                Y4mWriter::new(std::io::BufWriter::new(file), width, height, 10)
                    .map_err(|e| io(&y4m_path, e))?,
            )
        }
        _ => None,
    };
    for index in 0..frames {
        let (image, t) = match &renderer {
            Either::Synth(r) => r.render(index),
            Either::Terrain(r) => r.render(index),
        };
        truth.push_str(&truth_line(index, &t));
        match (&mut y4m, format) {
            (Some(w), _) => w.write(&image).map_err(|e| io(&y4m_path, e))?,
            (None, SynthFormat::Pgm) => {
                image_io::write_pnm(&out.join(format!("frame_{index:06}.pgm")), &image.to_grey())?
            }
            (None, _) => image_io::write_png(&out.join(format!("frame_{index:06}.png")), &image)?,
        }
    }
    if let Some(w) = y4m {
        w.finish().map_err(|e| io(&y4m_path, e))?;
    }
    let truth_path = out.join("truth.csv");
    std::fs::write(&truth_path, truth).map_err(|e| io(&truth_path, e))
}
