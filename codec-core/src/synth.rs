//! Synthetic animations for demos and tests (filled in by the synth work item).
