//! The terminal UI: the seed's property sheet (thesis ch. 5) in a terminal. One tab per
//! task, an Executive tab with the four lights per task, a vehicle list with link quality.
//!
//! [`App`] holds the model and what the user is doing; [`App::draw`] renders it and
//! [`App::handle_key`] turns keys into commands, so tests drive both through ratatui's
//! `TestBackend` without a terminal or a socket. [`run_terminal`] wires them to the real
//! terminal and link; a receive thread keeps draining the socket while the UI draws (as
//! the seed's secondary network thread did), so slow drawing never overflows the socket's
//! buffer.
//!
//! - [`app`]: the state and the keys;
//! - [`widgets`]: what each page draws;
//! - [`terminal`]: the real terminal and the receive thread.

mod app;
mod terminal;
mod widgets;

pub use app::*;
pub use terminal::run_terminal;

#[cfg(test)]
mod tests;
