//! Codec crate placeholder: filled in by its own issue; not yet registered.
