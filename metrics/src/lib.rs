//! Error metrics for mesh animations (filled in by the metrics issue).
