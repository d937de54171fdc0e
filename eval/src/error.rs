//! The one error type of `animcodec-eval`: callers match on what went wrong (a search that
//! found no stream meeting its target is [`EvalError::TargetMiss`], not a message to parse)
//! and every variant carries its cause, so `codec_core::error::message_with_sources` prints the
//! same line the command line always printed.

use crate::harness::target::{Target, TargetMiss};

/// Result alias of `animcodec-eval`.
pub type Result<T, E = EvalError> = std::result::Result<T, E>;

/// Everything the evaluation harness, the sweep rows and the descriptions can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A codec-core error: invalid parameters, a codec failure, a corrupt stream, a metric
    /// that cannot be computed, an output file that cannot be written.
    #[error(transparent)]
    Codec(#[from] codec_core::Error),

    /// No rate-ladder point of one codec meets the target (the miss names the best point
    /// reached). Boxed: it holds a whole measured point.
    #[error(transparent)]
    TargetMiss(Box<TargetMiss>),

    /// A search over several codecs found none meeting the target; each codec's miss, in order.
    #[error("no codec meets {target}: {}", misses.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    NoCodecMeetsTarget {
        /// The target.
        target: Target,
        /// Why each codec missed it.
        misses: Vec<TargetMiss>,
    },

    /// A search over several codecs stopped on a failure of one of them (other than a miss).
    #[error("{codec}: {source}")]
    InCodec {
        /// The codec being searched.
        codec: &'static str,
        /// What went wrong.
        source: Box<EvalError>,
    },

    /// A stream decoded to non-finite coordinates: garbage whatever its metrics say, never a
    /// measured point.
    #[error("{codec}: the stream decodes to non-finite coordinates")]
    NonFiniteDecode {
        /// The codec that wrote the stream.
        codec: &'static str,
    },

    /// A rate-ladder position past the ladder's end.
    #[error("{codec}: rate ladder step {step} does not exist (the ladder has {steps} steps)")]
    NoSuchLadderStep {
        /// The codec.
        codec: &'static str,
        /// The position asked for.
        step: usize,
        /// The ladder's length.
        steps: usize,
    },

    /// A codec declares an empty rate ladder, so there is nothing to search.
    #[error("{codec}: the rate ladder is empty")]
    EmptyLadder {
        /// The codec.
        codec: &'static str,
    },

    /// No configuration of a codec's declared search space validates.
    #[error("{codec}: no configuration of the search space validates{}", shown_on(on))]
    NoValidConfiguration {
        /// The codec.
        codec: &'static str,
        /// The base parameters the space was applied to, when the message should show them.
        on: Option<String>,
    },

    /// The thread pool of a sweep with a fixed number of threads could not be built.
    #[error("cannot set up {threads} sweep threads: {source}")]
    ThreadPool {
        /// Threads asked for.
        threads: usize,
        /// Rayon's reason.
        source: rayon::ThreadPoolBuildError,
    },

    /// A sweep row (gathered from another process) that does not read back: which row, which
    /// field, and why.
    #[error("sweep row{}: field '{field}' {reason}", row.map(|r| format!(" {r}")).unwrap_or_default())]
    Row {
        /// Position of the row among those read, when known.
        row: Option<usize>,
        /// The field (`bpvf`, `params.ss`, …), or `row` for the row as a whole.
        field: String,
        /// What is wrong with it.
        reason: String,
    },

    /// A value that cannot be a CSV cell (a row type that is not flat: a bug of the caller).
    #[error("cannot write the CSV: {0}")]
    Csv(String),

    /// A JSON document that cannot be built (a value serde_json cannot represent).
    #[error("cannot write the JSON document: {0}")]
    Json(#[from] serde_json::Error),

    /// A parameter given in a form its codec does not take (not `key=value`, given twice, a
    /// value of the wrong type); the message names the codec and the parameter.
    #[error("{0}")]
    Message(String),
}

/// ` on [base]` when the base parameters are to be shown.
fn shown_on(on: &Option<String>) -> String {
    on.as_ref().map(|base| format!(" on [{base}]")).unwrap_or_default()
}

impl From<TargetMiss> for EvalError {
    fn from(miss: TargetMiss) -> Self {
        EvalError::TargetMiss(Box::new(miss))
    }
}
