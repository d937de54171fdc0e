//! The argument groups several commands share, flattened into their argument structs: the
//! global options (limits, threads), STED's options, the metric switches, synthetic sizes.

use std::path::PathBuf;

use animcodec::formats::ReadOptions;
use animcodec::front::MetricOptions;
use animcodec::synth::SynthSize;
use clap::{Args, ValueEnum};

/// Options shared by every subcommand.
#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// Most memory a decode, or a glTF read, may hold in total (bytes; K, M, G suffixes are
    /// powers of 1024). Inputs needing more are rejected before allocating. Default 1G.
    #[arg(long, global = true, value_name = "BYTES", value_parser = super::parse_bytes)]
    pub max_memory: Option<u64>,

    /// Most arithmetic operations a decode may spend, counted from the stream's sizes before
    /// the work starts (the same count on every machine). Streams needing more are rejected
    /// before computing. Default 200 000 000 000 (about 186G; K, M, G suffixes are powers of
    /// 1024).
    #[arg(long, global = true, value_name = "OPS", value_parser = super::parse_bytes)]
    pub max_work: Option<u64>,

    /// Worker threads for codecs that parallelize (default: all cores; at most 4 × the cores,
    /// at least 8). Output bytes do not depend on it.
    #[arg(long, global = true, value_name = "N", value_parser = super::parse_workers)]
    pub threads: Option<u32>,
}

/// STED parameters (defaults: the metrics crate's `StedParams::default()`, which are the
/// metric author's tool's).
#[derive(Debug, Args)]
pub struct StedArgs {
    /// STED neighbourhood width in rings: the edges touching every vertex within R edge hops
    /// (1..=16; default 1).
    #[arg(long, value_name = "R")]
    pub sted_radius: Option<u32>,
    /// STED time extent of one frame step, in units of the diameter of reference frame 0
    /// (1e-9 to 1e9; default 0.0003).
    #[arg(long, value_name = "DT")]
    pub sted_dt: Option<f64>,
    /// STED speed-averaging window: the reference speed at frame f is the mean over temporal
    /// edges f−K+1 … f+K (1..=1000; default 5).
    #[arg(long, value_name = "K")]
    pub sted_window: Option<u32>,
    /// STED weight of the temporal part (0 to 1e9; default 9.144e-5).
    #[arg(long, value_name = "C")]
    pub sted_c: Option<f64>,
    /// Use absolute relative edge differences in STED's spatial part (default signed, as the
    /// metric author's tool).
    #[arg(long)]
    pub sted_absolute: bool,
}

impl StedArgs {
    /// The metric options these flags give (every metric computed).
    pub fn metric_options(&self) -> MetricOptions {
        MetricOptions {
            sted_radius: self.sted_radius,
            sted_dt: self.sted_dt,
            sted_window: self.sted_window,
            sted_c: self.sted_c,
            sted_absolute: self.sted_absolute,
            ..MetricOptions::default()
        }
    }
}

/// The metric switches `eval` and `sweep` share.
#[derive(Debug, Args)]
pub struct MetricArgs {
    /// STED options.
    #[command(flatten)]
    pub sted: StedArgs,

    /// Skip STED.
    #[arg(long)]
    pub no_sted: bool,

    /// Skip the Hausdorff distance.
    #[arg(long)]
    pub no_hausdorff: bool,
}

impl MetricArgs {
    /// The metric options these flags give.
    pub fn metric_options(&self) -> MetricOptions {
        MetricOptions { skip_sted: self.no_sted, skip_hausdorff: self.no_hausdorff, ..self.sted.metric_options() }
    }
}

/// How one input file is read: the options of [`ReadOptions`] a user sets.
#[derive(Debug, Args)]
pub struct ReadArgs {
    /// OBJ file giving the triangles of a .pc2/.mdd cache (default: the OBJ beside it with the
    /// same stem).
    #[arg(long, value_name = "OBJ")]
    pub topology: Option<PathBuf>,

    /// glTF input: the animation to play, by name or index (default: the first; `animcodec
    /// list-animations FILE` lists them).
    #[arg(long, value_name = "NAME|INDEX")]
    pub animation: Option<String>,

    /// Alembic input: the mesh object to read, by full path (`/root/char/body`), or an object
    /// whose meshes are read (default: every mesh, merged; `animcodec list-animations FILE.abc`
    /// lists them).
    #[arg(long, value_name = "PATH")]
    pub object: Option<String>,
}

impl ReadArgs {
    /// The read options, with `frame_rate` for an input that stores none.
    pub fn options(&self, frame_rate: Option<f32>) -> ReadOptions {
        ReadOptions {
            topology: self.topology.clone(),
            frame_rate,
            animation: self.animation.clone(),
            object: self.object.clone(),
        }
    }
}

/// Parses an error target such as `kg=0.5` (`encode --target`, `export --target`).
pub fn parse_target(text: &str) -> Result<animcodec::harness::Target, String> {
    text.parse()
}

/// Size presets of the synthetic animations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SizeArg {
    /// A few hundred vertices × 40 frames.
    Small,
    /// About 2.5k vertices × 120 frames.
    Medium,
    /// About 10k vertices × 300 frames.
    Large,
}

impl From<SizeArg> for SynthSize {
    fn from(s: SizeArg) -> Self {
        match s {
            SizeArg::Small => SynthSize::Small,
            SizeArg::Medium => SynthSize::Medium,
            SizeArg::Large => SynthSize::Large,
        }
    }
}
