//! The command line's commands, one module each; main.rs keeps the command enum and `main`.
pub(crate) mod args;
pub(crate) mod bench;
pub(crate) mod film;
pub(crate) mod info;
pub(crate) mod interrupt;
pub(crate) mod outputs;
pub(crate) mod render;
pub(crate) mod values;
pub(crate) mod view;
