//! Runtime relighting.
