//! The `gwml` command-line tool.

mod cluster;
mod commands;
mod compare;
mod explain;
mod learn;
mod qscan;
mod repl;
mod scan;
mod strain_input;

use clap::{Parser, Subcommand, ValueEnum};
use gwml::compiler::ir::{MathMode, Multiband, Precision, RelativeBinning, UnknownSetting};
use gwml_lab::experiment;
use gwml_lab::generator::{self, GeneratorCommand};
use gwml_lab::synth::GlitchClass;
use std::path::PathBuf;
use std::process::ExitCode;

/// gwml: a differentiable modelling language and compiler for
/// gravitational-wave data analysis.
#[derive(Parser)]
#[command(name = "gwml", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Check a model, differentiate it, JIT-compile it and report.
    Compile(CompileArgs),
    /// Time a scene under every precision/math setting and measure each one's error against f64-exact.
    ///
    /// Each setting is timed twice: a forward call computing every output,
    /// and (scenes with `grad`) a value-and-gradient call compiled with only
    /// the differentiated outputs, as a sampler or optimiser calls it.
    Tradeoff(TradeoffArgs),
    /// Evaluate a scene's outputs (and gradients with --grad).
    Run(RunArgs),
    /// Minimise a scene's scalar loss over the params of its `grad` statement
    /// (within their bounds) and report Fisher-matrix uncertainties.
    Fit(FitArgs),
    /// Fit several scenes to the same data and rank them by Laplace log
    /// evidence and BIC: which model explains the data.
    Compare(compare::CompareArgs),
    /// Train the learned components of a scene on a NumPy dataset (weights
    /// and the params its `grad` names), with validation, early stopping and
    /// safetensors checkpoints.
    Train(TrainArgs),
    /// Apply trained weights to each row of NumPy inputs and write outputs.
    Predict(PredictArgs),
    /// Write synthetic data: labelled datasets (.npz) or long strain in GWOSC layout (.hdf5).
    #[command(subcommand)]
    Data(DataCommand),
    /// Scan strain files for glitches: PSD, whitening, Q-tile triggers, classification
    /// (files at a whole multiple of the classifier's rate, such as GWOSC's 16384 Hz, are
    /// decimated to it).
    Scan(scan::ScanArgs),
    /// Q-transform images of whitened strain around a GPS time (PNG), at
    /// Gravity Spy's four durations.
    Qscan(qscan::QscanArgs),
    /// Explain a glitch: fit every glitch family and a chirp to the whitened
    /// strain around a GPS time, rank them by Bayes factor (and against
    /// noise), and name a likely cause.
    Explain(explain::ExplainArgs),
    /// Run a reference experiment end to end and write its tables and plots.
    Experiment(ExperimentArgs),
    /// The learned glitch generator: fit one glitch family's distribution
    /// to example glitches, or draw new glitches from a fitted one.
    #[command(subcommand)]
    Generator(GeneratorCommand),
    /// An interactive session: define, evaluate, differentiate, inspect, time.
    /// Reads piped standard input line by line (exit status 1 if any line failed).
    Repl,
}

/// Which stage's text to print.
#[derive(Clone, Copy, ValueEnum)]
pub enum Emit {
    /// The parsed syntax tree.
    Ast,
    /// The scene's IR, pruned to what its outputs need (before rescaling: in mixed precision its `f64` marks include values rescaling later brings into f32's range).
    Ir,
    /// Forward and adjoint IR after simplification, specialisation and rescaling: what the gradient kernel runs (`f64` marks what mixed precision computes in f64).
    Adjoint,
    /// Cranelift IR of the kernel (the gradient kernel if the scene asks for gradients).
    Clif,
    /// Machine code of that kernel after register allocation (Cranelift's listing: loops, spills to the stack, vector instructions).
    Asm,
}

/// Parses a `--precision` or `--math` value with the compiler's own
/// parser of the setting (the one the scene's `precision:`/`math:` and the
/// REPL use).
fn setting<T: std::str::FromStr<Err = UnknownSetting>>(s: &str) -> Result<T, String> {
    s.parse().map_err(|e: UnknownSetting| format!("{e}; use {}", e.help))
}

/// Overrides of a scene's speed/accuracy knobs.
#[derive(clap::Args, Clone)]
pub struct KnobArgs {
    /// Override the scene's precision knob: f64; f32 (reductions still
    /// accumulate in 64-bit; values far outside f32's range, such as strains
    /// of 1e-23, are stored scaled by powers of two); or mixed (f32, rescaled
    /// as f32 is, except phases — what flows into sin, cos, tan or a complex
    /// exp — and reductions, which are 64-bit; `--emit adjoint` marks them `f64`).
    #[arg(long, value_name = "f64|f32|mixed", value_parser = setting::<Precision>)]
    pub precision: Option<Precision>,
    /// Override the scene's math knob, how generated code computes sin, cos,
    /// exp, log, cbrt and pow: exact (libm accuracy: inline code within 2 ulp
    /// of glibc where that is faster, libm otherwise), fast (inline
    /// polynomials, ~1e-12 relative error) or fastest (~1e-7).
    #[arg(long, value_name = "exact|fast|fastest", value_parser = setting::<MathMode>)]
    pub math: Option<MathMode>,
    /// Override the scene's multiband setting: off, or the largest phase
    /// error in radians (e.g. 1e-3) of waveform phases computed on a coarse
    /// subset of their grid and interpolated, `e^{iφ}` advanced by rotation
    /// between the nodes (`--emit ir` lists the nodes chosen).
    #[arg(long, value_name = "off|TOLERANCE", value_parser = setting::<Multiband>)]
    pub multiband: Option<Multiband>,
    /// Override the scene's relative_binning setting: off, or a number of
    /// frequency bins (e.g. 100). Likelihood sums quadratic in a waveform
    /// are computed from summary data of the waveform at the params'
    /// defaults (the fiducial), the waveform evaluated at the bins' edges
    /// only (`--emit ir` lists them).
    #[arg(long, value_name = "off|BINS", value_parser = setting::<RelativeBinning>)]
    pub relative_binning: Option<RelativeBinning>,
    /// Set one of the scene's `knob` declarations: NAME=VALUE, the value
    /// written as in the scene, with its unit (`--knob df="0.25 Hz"`,
    /// `--knob pn_order=5`). Repeatable.
    #[arg(long = "knob", value_name = "NAME=VALUE")]
    pub knobs: Vec<String>,
}

/// How `run` prints results.
#[derive(Clone, Copy, ValueEnum, PartialEq)]
pub enum Format {
    /// Aligned, human-readable.
    Text,
    /// `{"params": {...}, "outputs": {...}, "grads": {OUTPUT: {PARAM: value}}}`.
    Json,
}

#[derive(clap::Args)]
pub struct CompileArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scene to compile (optional when the file has one scene).
    #[arg(long)]
    pub scene: Option<String>,
    /// Print one stage's output instead of the summary.
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
    #[command(flatten)]
    pub knobs: KnobArgs,
    /// Print op counts per stage, kernel counts and compile time per stage.
    #[arg(long)]
    pub stats: bool,
    /// Verify the IR after every pass (debug builds always do; so does any
    /// command with GWML_VERIFY=1 in the environment). A failure is an
    /// internal compiler error naming the pass.
    #[arg(long)]
    pub verify: bool,
}

/// Param values and input data bound before running.
#[derive(clap::Args)]
pub struct BindArgs {
    /// Set a param (for `fit`, the starting value of a free param): `--set mc=30`
    /// in its declared unit, or with a unit converted to it: `--set "tc=2 ms"`.
    /// With relative binning, `--set "fiducial.mc=28.1 Msun"` sets the fiducial.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Bind an input to a 1-D .npy file (float64/32 or complex128/64): `--input d=data.npy`; or a real input
    /// over a frequency grid to a two-column noise-curve text file (Hz, value), interpolated log-log onto the
    /// grid: `--input psd=FILE.txt` (PSD values) or `--input psd=asd:FILE.txt` (ASD values, squared).
    #[arg(long = "input", value_name = "NAME=PATH")]
    pub input: Vec<String>,
}

#[derive(clap::Args)]
pub struct RunArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scene to run (optional when the file has one scene).
    #[arg(long)]
    pub scene: Option<String>,
    #[command(flatten)]
    pub bind: BindArgs,
    /// Write an array output to a .npy file: `--output h=h.npy`.
    #[arg(long = "output", value_name = "NAME=PATH.npy")]
    pub output: Vec<String>,
    /// Also compute the gradients the scene declares (one fused kernel).
    #[arg(long)]
    pub grad: bool,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
    #[command(flatten)]
    pub knobs: KnobArgs,
}

/// The optimiser `fit` runs.
#[derive(Clone, Copy, ValueEnum)]
pub enum OptimizerArg {
    /// Limited-memory BFGS with a backtracking (Armijo) line search.
    Lbfgs,
    /// Adam with a cosine-decayed learning rate.
    Adam,
}

#[derive(clap::Args)]
pub struct FitArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scene to fit (optional when the file has one scene).
    #[arg(long)]
    pub scene: Option<String>,
    #[command(flatten)]
    pub bind: BindArgs,
    /// The real scalar output to minimise (needed when several have gradients).
    #[arg(long, value_name = "NAME")]
    pub output: Option<String>,
    /// The optimiser.
    #[arg(long, value_enum, default_value = "lbfgs")]
    pub optimizer: OptimizerArg,
    /// Maximum number of iterations [default: 500 for lbfgs, 3000 for adam].
    #[arg(long, value_name = "N")]
    pub steps: Option<usize>,
    /// Adam's initial learning rate in the unconstrained variables [default: 0.02].
    #[arg(long, value_name = "RATE")]
    pub learning_rate: Option<f64>,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
    /// Do not print progress lines (they go to standard error).
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    pub knobs: KnobArgs,
}

/// Optimisers of `gwml train`.
#[derive(Clone, Copy, ValueEnum)]
pub enum TrainOptimizerArg {
    /// Adam (Kingma & Ba 2015), betas 0.9 / 0.999.
    Adam,
    /// Adam with decoupled weight decay (Loshchilov & Hutter 2019).
    Adamw,
    /// Stochastic gradient descent with momentum.
    Sgd,
}

/// Learning-rate schedules of `gwml train`.
#[derive(Clone, Copy, ValueEnum)]
pub enum ScheduleArg {
    /// The same rate throughout.
    Constant,
    /// Multiplied by --gamma every --step-epochs epochs.
    Step,
    /// Cosine decay to zero over all epochs.
    Cosine,
}

#[derive(clap::Args)]
pub struct TrainArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scene to train (optional when the file has one scene).
    #[arg(long)]
    pub scene: Option<String>,
    /// Training data: .npz (or .npy) whose arrays are named like the scene's
    /// inputs, one row per example; class labels may be a 1-D integer array
    /// for a one-hot input.
    #[arg(long, value_name = "PATH.npz")]
    pub data: PathBuf,
    /// Validation data, in the same form.
    #[arg(long, value_name = "PATH.npz")]
    pub val: Option<PathBuf>,
    /// Passes over the training data.
    #[arg(long, default_value_t = 10)]
    pub epochs: usize,
    /// Examples per gradient step.
    #[arg(long, default_value_t = 32)]
    pub batch: usize,
    /// Learning rate.
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f64,
    /// Optimiser.
    #[arg(long, value_enum, default_value = "adam")]
    pub optimizer: TrainOptimizerArg,
    /// Weight decay of adamw.
    #[arg(long, default_value_t = 0.01)]
    pub weight_decay: f64,
    /// Momentum of sgd.
    #[arg(long, default_value_t = 0.9)]
    pub momentum: f64,
    /// Learning-rate schedule.
    #[arg(long, value_enum, default_value = "constant")]
    pub schedule: ScheduleArg,
    /// Epochs between decays of the step schedule.
    #[arg(long, default_value_t = 5)]
    pub step_epochs: usize,
    /// Factor of each decay of the step schedule.
    #[arg(long, default_value_t = 0.5)]
    pub gamma: f64,
    /// Clip the gradient to this global L2 norm.
    #[arg(long, value_name = "NORM")]
    pub clip: Option<f64>,
    /// Seed of the shuffles (training is deterministic for a seed and thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Stop after this many epochs without a lower validation loss.
    #[arg(long, value_name = "EPOCHS")]
    pub patience: Option<usize>,
    /// Directory for checkpoints: last.safetensors each epoch, best.safetensors at the lowest validation loss.
    #[arg(long, value_name = "DIR")]
    pub checkpoint: Option<PathBuf>,
    /// Continue from DIR/last.safetensors (bit for bit, with the same seed and threads).
    #[arg(long)]
    pub resume: bool,
    /// The output to minimise.
    #[arg(long, default_value = "loss")]
    pub loss: String,
    /// The output whose largest element is the predicted class (for accuracy).
    #[arg(long, default_value = "logits")]
    pub logits: String,
    /// The input holding the labels (for accuracy).
    #[arg(long, default_value = "label")]
    pub label: String,
    /// Plot training and validation loss per epoch to a PNG.
    #[arg(long, value_name = "PATH.png")]
    pub plot: Option<PathBuf>,
    /// Write the loss curve as CSV, one row per epoch (epoch, train_loss,
    /// train_accuracy, val_loss, val_accuracy, lr; values in full precision).
    #[arg(long, value_name = "PATH.csv")]
    pub history: Option<PathBuf>,
    /// No progress bar or per-epoch lines (they go to standard error).
    #[arg(long, short)]
    pub quiet: bool,
    /// Run as one rank of an MPI job (`mpirun -n N gwml train --mpi ...`):
    /// data-parallel, each rank computes its share of every batch and the
    /// gradients are summed over ranks (an allreduce) before each step, so
    /// N ranks at --batch B follow one process at --batch B. Rank 0 prints
    /// and writes checkpoints. Needs gwml built with `--features mpi`.
    #[arg(long)]
    pub mpi: bool,
    #[command(flatten)]
    pub knobs: KnobArgs,
}

#[derive(clap::Args)]
pub struct PredictArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scene to run (optional when the file has one scene).
    #[arg(long)]
    pub scene: Option<String>,
    /// A checkpoint written by `gwml train`.
    #[arg(long, value_name = "CKPT.safetensors")]
    pub weights: PathBuf,
    /// An input with one row per example: `--input x=X.npy`, or from a .npz the array named like
    /// the input (`--input x=data.npz`, as `gwml data` writes) or named after a colon
    /// (`--input x=data.npz:signal`).
    #[arg(long = "input", value_name = "NAME=PATH.npy")]
    pub input: Vec<String>,
    /// Write an output, one row per example: `--output logits=Y.npy`.
    #[arg(long = "output", value_name = "NAME=PATH.npy")]
    pub output: Vec<String>,
    #[command(flatten)]
    pub knobs: KnobArgs,
}

/// Kinds of synthetic data.
#[derive(Subcommand)]
pub enum DataCommand {
    /// Sine-Gaussian bursts in white noise (label 1) or noise alone (label 0):
    /// `x` of 256 samples at 256 Hz, f0 20-100 Hz, Q 3-12.
    Bursts(DataArgs),
    /// Whitened 1 s segments at 4096 Hz of eight classes (label 0 None, 1 Blip,
    /// 2 Koi Fish, 3 Whistle, 4 Scratchy, 5 Chirp, 6 Tomte, 7 Scattered
    /// Light) in aLIGO noise, each class at its own SNR range after Gravity
    /// Spy (see --snr); `x` is n × 4096.
    Glitch(DataArgs),
    /// Long strain at 4096 Hz in GWOSC HDF5 layout: coloured Gaussian noise
    /// from a PSD, glitches injected at known times (listed by --truth),
    /// optional missing data.
    Strain(scan::StrainArgs),
}

#[derive(clap::Args)]
pub struct DataArgs {
    /// Number of examples.
    #[arg(long, default_value_t = 1000)]
    pub n: usize,
    /// Seed (use different seeds for training, validation and test sets).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Range of the optimal signal-to-noise ratio [default: 6..15 for bursts;
    /// for glitch, each class's own range after Gravity Spy (Blip 6.5-100,
    /// Koi Fish 12-400, ...), drawn log-uniformly, and a real Koi Fish
    /// fit's shape at its own SNR; a range given here is drawn uniformly
    /// for every class].
    #[arg(long)]
    pub snr: Option<String>,
    /// glitch only: shift the noise's PSD away from the modelled one by a
    /// factor 1 + (KNEE/f)² over 20 Hz–2 kHz (excess low-frequency noise),
    /// for generalisation tests [default: 0, the modelled PSD].
    #[arg(long, value_name = "HZ", default_value_t = 0.0)]
    pub psd_knee: f64,
    /// glitch only: draw only this class [default: all eight, uniformly].
    #[arg(long, value_enum)]
    pub class: Option<GlitchClass>,
    /// glitch only: centre signals as a scan's trigger window does (energy
    /// centres at 0.4-0.6 s instead of 0.3-0.7 s), for classifiers `gwml scan` runs.
    #[arg(long)]
    pub centred: bool,
    /// glitch only: unit-variance Gaussian noise alone, without the flaws of
    /// whitened real strain (a misestimated PSD, residual 60 Hz and violin
    /// lines, weak background transients).
    #[arg(long)]
    pub ideal_noise: bool,
    /// glitch only: draw the shapes of a class from a generator fitted by
    /// `gwml generator fit` (the file says which classes it draws) instead
    /// of its formula, each scaled to the --snr range; repeat for several
    /// generators (at most one per class).
    #[arg(long, value_name = "GEN.json")]
    pub generator: Vec<PathBuf>,
    /// glitch only: the chance that a row of a class a --generator draws
    /// takes the generator's shape; the others keep their formula's (or a
    /// real fit's) shape, as without --generator.
    #[arg(long, value_name = "FRACTION", default_value_t = 1.0)]
    pub generator_share: f64,
    /// The .npz file to write.
    #[arg(long, value_name = "PATH.npz")]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct ExperimentArgs {
    /// Which experiment.
    #[arg(value_enum)]
    pub which: ExperimentKind,
    /// `glitch`: every method, table and plot at small sizes, a check that
    /// the pipeline runs (about 2 minutes on 2 cores; its numbers are not
    /// the benchmark's).
    #[arg(long, conflicts_with = "standard")]
    pub quick: bool,
    /// `glitch`: training sets of 500, 1,500 and 5,000, two seeds each: the
    /// README's tables (~15 minutes on 2 cores). Without either flag, the
    /// full run: up to 50,000 examples, five seeds (hours).
    #[arg(long)]
    pub standard: bool,
    /// Directory for the tables (Markdown, CSV) and plots (PNG) [default:
    /// results/glitch, results/explain].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// `explain`: injections per glitch class.
    #[arg(long, default_value_t = 100)]
    pub per_class: usize,
    /// `explain`: seed of the simulated strain.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// `explain`: the injections' optimal SNR range, e.g. 10..30, drawn
    /// uniformly for every class [default: each class's own range after
    /// Gravity Spy (Blip 6.5-100, Koi Fish 12-400, ...), log-uniformly,
    /// from SNR 10 up].
    #[arg(long, value_name = "LO..HI")]
    pub snr: Option<String>,
    /// `glitch`: worker threads [default: all cores]; `explain` runs on one.
    #[arg(long)]
    pub threads: Option<usize>,
    /// `explain`: only this class (e.g. Whistle, koi_fish); repeat for
    /// several [default: every glitch class and Chirp]. A class's
    /// injections do not depend on which others run.
    #[arg(long = "class", value_name = "NAME")]
    pub classes: Vec<String>,
}

/// The experiments `gwml experiment` runs.
#[derive(Clone, Copy, ValueEnum)]
pub enum ExperimentKind {
    /// Glitch classification: a rule-based filter bank, a CNN on the
    /// strain, a Gravity Spy-style CNN on Q-scans and a differentiable
    /// template bank with a network head, on the same data (issue #7's
    /// reference experiment).
    Glitch,
    /// `gwml explain` on injections of every glitch family and a chirp into
    /// simulated strain: how often the right family wins, pulls of the
    /// recovered params, time per trigger (issue #24's campaign).
    Explain,
}

#[derive(clap::Args)]
pub struct TradeoffArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scene to measure (optional when the file has one scene).
    #[arg(long)]
    pub scene: Option<String>,
    #[command(flatten)]
    pub bind: BindArgs,
    /// Precisions to sweep, comma-separated (f64, f32, mixed) [default: all].
    #[arg(long, value_name = "PRECISION,...", value_delimiter = ',', value_parser = setting::<Precision>)]
    pub precision: Vec<Precision>,
    /// Math modes to sweep, comma-separated (exact, fast, fastest) [default: all].
    #[arg(long, value_name = "MATH,...", value_delimiter = ',', value_parser = setting::<MathMode>)]
    pub math: Vec<MathMode>,
    /// Multibanding tolerances to sweep, comma-separated: `off` or the
    /// largest phase error in radians (`off,1e-3`) [default: off, 1e-2, 2e-3,
    /// 1e-3 and 1e-4 for scenes with a waveform phase over a grid, else off].
    #[arg(long, value_name = "TOL,...", value_delimiter = ',', value_parser = setting::<Multiband>)]
    pub multiband: Vec<Multiband>,
    /// Relative-binning bin counts to sweep, comma-separated: `off` or a
    /// number of bins (`off,100`) [default: off, 50, 100 and 200 for scenes
    /// with a likelihood sum over a waveform, unless --multiband is given].
    /// Each is measured with multibanding off.
    #[arg(long, value_name = "BINS,...", value_delimiter = ',', value_parser = setting::<RelativeBinning>)]
    pub relative_binning: Vec<RelativeBinning>,
    /// Also sweep one of the scene's `knob` declarations over comma-separated
    /// values, NAME=V1,V2,... (`--sweep df="0.25 Hz,0.5 Hz"`,
    /// `--sweep pn_order=4,6`); repeatable (every combination is measured).
    /// The reference keeps the scene's own value (or the `--knob` one).
    #[arg(long, value_name = "NAME=V1,V2,...")]
    pub sweep: Vec<String>,
    /// Set one of the scene's `knob` declarations for every row, the
    /// reference included: NAME=VALUE, written as in the scene
    /// (`--knob df="0.25 Hz"`); repeatable.
    #[arg(long, value_name = "NAME=VALUE")]
    pub knob: Vec<String>,
    /// Timed calls per configuration and kernel (medians are reported).
    #[arg(long, default_value_t = 200)]
    pub reps: usize,
    /// A real array output holding the PSD that weights the waveform mismatch.
    #[arg(long, value_name = "OUTPUT")]
    pub psd: Option<String>,
    /// Write the rows as CSV.
    #[arg(long, value_name = "PATH.csv")]
    pub csv: Option<PathBuf>,
    /// Write the rows as JSON.
    #[arg(long, value_name = "PATH.json")]
    pub json: Option<PathBuf>,
    /// Plot time against error as a PNG.
    #[arg(long, value_name = "PATH.png")]
    pub plot: Option<PathBuf>,
}

/// A reader that stops early (`gwml ... | head`) closes the pipe; printing
/// then fails with a broken pipe, which `println!` turns into a panic. Exit
/// quietly instead, with the status of a process a SIGPIPE ended (141).
fn exit_quietly_on_broken_pipe() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload.downcast_ref::<String>().map(String::as_str).or_else(|| payload.downcast_ref::<&str>().copied());
        if message.is_some_and(|m| m.contains("Broken pipe")) {
            std::process::exit(141);
        }
        report(info);
    }));
}

fn main() -> ExitCode {
    exit_quietly_on_broken_pipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Compile(a) => commands::compile(a),
        Command::Run(a) => commands::run(a),
        Command::Fit(a) => commands::fit(a),
        Command::Compare(a) => compare::compare(a),
        Command::Tradeoff(a) => commands::tradeoff(a),
        Command::Train(a) => learn::train(a),
        Command::Predict(a) => learn::predict(a),
        Command::Data(DataCommand::Bursts(a)) => learn::data(a, false),
        Command::Data(DataCommand::Glitch(a)) => learn::data(a, true),
        Command::Data(DataCommand::Strain(a)) => scan::data_strain(a),
        Command::Scan(a) => scan::scan(a),
        Command::Qscan(a) => qscan::qscan(a),
        Command::Explain(a) => explain::explain(a),
        Command::Generator(GeneratorCommand::Fit(a)) => generator::fit_command(a),
        Command::Generator(GeneratorCommand::Sample(a)) => generator::sample_command(a),
        Command::Experiment(a) => match a.which {
            ExperimentKind::Glitch => experiment::glitch(&experiment::GlitchExperiment {
                budget: match (a.quick, a.standard) {
                    (true, _) => experiment::Budget::Quick,
                    (_, true) => experiment::Budget::Standard,
                    _ => experiment::Budget::Full,
                },
                out: a.out.unwrap_or_else(|| "results/glitch".into()),
                threads: a.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
            }),
            ExperimentKind::Explain => {
                let snr = a.snr.as_deref().map(gwml_lab::parse_range).transpose();
                let classes = a.classes.iter().map(|c| gwml_lab::synth::glitch_class(c)).collect::<Result<Vec<usize>, String>>();
                snr.and_then(|snr| {
                    let out = a.out.unwrap_or_else(|| "results/explain".into());
                    explain::campaign(&out, a.per_class, a.seed, snr, classes?)
                })
            }
        },
        Command::Repl => {
            let failures = repl::run();
            return if failures == 0 { ExitCode::SUCCESS } else { ExitCode::FAILURE };
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // An empty message: already reported (by MPI rank 0).
        Err(msg) if msg.is_empty() => ExitCode::FAILURE,
        Err(msg) => {
            eprint!("{msg}");
            if !msg.ends_with('\n') {
                eprintln!();
            }
            ExitCode::FAILURE
        }
    }
}
