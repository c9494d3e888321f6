//! The terminal UI.

use crate::net::Session;

pub fn run_terminal(_session: Session, _vehicle: Option<u16>) -> std::io::Result<()> {
    Ok(())
}
