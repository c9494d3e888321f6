//! The real terminal: raw mode, a receive thread that keeps draining the socket while the
//! UI draws, and the key loop.

use super::app::App;
use crate::net::{CommandTarget, Received, Session};
use ratatui::crossterm::event::{self, Event};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Runs the UI on the real terminal until `q`.
pub fn run_terminal(session: Session, vehicle: Option<u16>) -> std::io::Result<()> {
    let Session {
        link,
        model,
        mut sender,
    } = session;
    let receiver_link = link.try_clone()?;
    let (tx, rx) = mpsc::channel::<(Received, Instant)>();
    std::thread::spawn(move || {
        let mut receiver_link = receiver_link;
        loop {
            match receiver_link.receive(Duration::from_millis(200)) {
                Ok(Some(received)) => {
                    if tx.send((received, Instant::now())).is_err() {
                        return;
                    }
                }
                Ok(None) => {}
                Err(_) => std::thread::sleep(Duration::from_millis(200)),
            }
        }
    });
    let mut app = App::new(model, vehicle, sender.is_some());
    let mut terminal = ratatui::init();
    let result = (|| -> std::io::Result<()> {
        while !app.quit {
            while let Ok((received, at)) = rx.try_recv() {
                app.apply(&received, at);
            }
            let now = Instant::now();
            let resend = app.tick(now);
            terminal.draw(|frame| app.draw(frame, now))?;
            let request = match resend {
                Some(request) => request,
                None => {
                    if !event::poll(Duration::from_millis(100))? {
                        continue;
                    }
                    let Event::Key(key) = event::read()? else {
                        continue;
                    };
                    let Some(request) = app.handle_key(key) else {
                        continue;
                    };
                    request
                }
            };
            let Some(sender) = sender.as_mut() else {
                app.status = "no link key: commands need --key FILE".to_string();
                continue;
            };
            let Some(v) = app.model.vehicle(request.vehicle_id) else {
                continue;
            };
            let target = CommandTarget {
                vehicle_id: v.id,
                run_id: v.run_id,
                address: v.address,
            };
            match link.send_command(&target, sender, &request.command) {
                Ok(sequence) => app.sent(&request, sender.sender_id, sequence, Instant::now()),
                Err(e) => app.status = format!("{}: {e}", request.description),
            }
        }
        Ok(())
    })();
    ratatui::restore();
    result
}
