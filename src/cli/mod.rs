//! The command line's commands, one module each: their arguments and bodies, in the library so that the binary
//! (src/main.rs keeps the command enum and `main`) and the Python module (python/) share one definition of every
//! option, its checks and its messages.
pub mod args;
pub mod bench;
pub mod film;
pub mod info;
pub mod interrupt;
pub mod outputs;
pub mod render;
pub mod shot;
pub mod values;
pub mod view;
