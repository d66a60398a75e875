//! Scripted key presses for the viewer (`radiosity view --keys`): the keys
//! a user would press, named as `winit` names them, pressed one after each
//! drawn frame. For demonstrations that must repeat exactly, and for the
//! tests, which drive the window's whole key path (key → light edit →
//! frame → screenshot or saved lights) under Xvfb, where no one types.

use std::collections::VecDeque;
use winit::keyboard::KeyCode;

/// The keys the viewer acts on ([`super::HELP`]), by `winit`'s names.
/// Ctrl+S is not among them: F5 saves the same way.
pub const NAMES: &[(&str, KeyCode)] = &[
    ("Escape", KeyCode::Escape),
    ("Digit1", KeyCode::Digit1),
    ("Digit2", KeyCode::Digit2),
    ("Digit3", KeyCode::Digit3),
    ("Digit4", KeyCode::Digit4),
    ("Digit5", KeyCode::Digit5),
    ("KeyW", KeyCode::KeyW),
    ("KeyA", KeyCode::KeyA),
    ("KeyS", KeyCode::KeyS),
    ("KeyD", KeyCode::KeyD),
    ("KeyQ", KeyCode::KeyQ),
    ("KeyE", KeyCode::KeyE),
    ("Tab", KeyCode::Tab),
    ("ArrowLeft", KeyCode::ArrowLeft),
    ("ArrowRight", KeyCode::ArrowRight),
    ("ArrowUp", KeyCode::ArrowUp),
    ("ArrowDown", KeyCode::ArrowDown),
    ("PageUp", KeyCode::PageUp),
    ("PageDown", KeyCode::PageDown),
    ("KeyI", KeyCode::KeyI),
    ("KeyJ", KeyCode::KeyJ),
    ("KeyK", KeyCode::KeyK),
    ("KeyL", KeyCode::KeyL),
    ("Equal", KeyCode::Equal),
    ("Minus", KeyCode::Minus),
    ("NumpadAdd", KeyCode::NumpadAdd),
    ("NumpadSubtract", KeyCode::NumpadSubtract),
    ("BracketLeft", KeyCode::BracketLeft),
    ("BracketRight", KeyCode::BracketRight),
    ("KeyC", KeyCode::KeyC),
    ("KeyN", KeyCode::KeyN),
    ("KeyB", KeyCode::KeyB),
    ("KeyG", KeyCode::KeyG),
    ("Delete", KeyCode::Delete),
    ("Backspace", KeyCode::Backspace),
    ("KeyM", KeyCode::KeyM),
    ("KeyX", KeyCode::KeyX),
    ("KeyP", KeyCode::KeyP),
    ("F12", KeyCode::F12),
    ("F5", KeyCode::F5),
    ("KeyH", KeyCode::KeyH),
    ("KeyY", KeyCode::KeyY),
    ("KeyR", KeyCode::KeyR),
    ("KeyF", KeyCode::KeyF),
    ("KeyU", KeyCode::KeyU),
    ("KeyO", KeyCode::KeyO),
    ("KeyT", KeyCode::KeyT),
    ("KeyV", KeyCode::KeyV),
];

/// The most presses a script may hold (each is at least one frame).
pub const MAX_PRESSES: usize = 100_000;

/// Key presses still to come, in order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KeyScript {
    keys: VecDeque<KeyCode>,
}

/// Why a script was refused: the item and what was wrong with it.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum KeyScriptError {
    #[error("key {0:?} is not one the viewer acts on; the keys are: {names}", names = names())]
    UnknownKey(String),
    #[error("{0:?}: the count after '*' must be a whole number from 1 to {MAX_PRESSES}")]
    BadCount(String),
    #[error("{0} presses: at most {MAX_PRESSES}")]
    TooMany(usize),
}

fn names() -> String {
    NAMES.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(" ")
}

impl KeyScript {
    /// Parses comma-separated key names, each optionally followed by
    /// `*COUNT` (`"KeyB,ArrowLeft*3,F5"`); spaces around items are
    /// ignored, an empty text is no keys.
    pub fn parse(text: &str) -> Result<KeyScript, KeyScriptError> {
        let mut keys = VecDeque::new();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, count) = match item.split_once('*') {
                Some((name, count)) => {
                    let k = count
                        .trim()
                        .parse::<usize>()
                        .ok()
                        .filter(|k| (1..=MAX_PRESSES).contains(k))
                        .ok_or_else(|| KeyScriptError::BadCount(item.to_string()))?;
                    (name.trim(), k)
                }
                None => (item, 1),
            };
            let code = NAMES
                .iter()
                .find(|(n, _)| *n == name)
                .map(|&(_, c)| c)
                .ok_or_else(|| KeyScriptError::UnknownKey(name.to_string()))?;
            if keys.len() + count > MAX_PRESSES {
                return Err(KeyScriptError::TooMany(keys.len() + count));
            }
            keys.extend(std::iter::repeat_n(code, count));
        }
        Ok(KeyScript { keys })
    }

    /// Presses still to come.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The next press, taken off the script.
    pub fn next_key(&mut self) -> Option<KeyCode> {
        self.keys.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_parse_with_counts_and_refuse_what_they_cannot_press() {
        let mut s = KeyScript::parse(" KeyB, ArrowLeft*3 ,F5,").unwrap();
        assert_eq!(s.len(), 5);
        let got: Vec<KeyCode> = std::iter::from_fn(|| s.next_key()).collect();
        use KeyCode::*;
        assert_eq!(got, [KeyB, ArrowLeft, ArrowLeft, ArrowLeft, F5]);
        assert!(KeyScript::parse("").unwrap().is_empty());
        let e = KeyScript::parse("KeyB,keyb").unwrap_err();
        assert_eq!(e, KeyScriptError::UnknownKey("keyb".into()));
        assert!(e.to_string().contains("KeyN"), "{e}");
        for bad in ["KeyN*0", "KeyN*x", "KeyN*-1", "KeyN*100001"] {
            assert_eq!(
                KeyScript::parse(bad).unwrap_err(),
                KeyScriptError::BadCount(bad.into())
            );
        }
        assert_eq!(
            KeyScript::parse("KeyN*60000,KeyB*60000").unwrap_err(),
            KeyScriptError::TooMany(120_000)
        );
        // Every name is distinct and parses to its key.
        for (n, c) in NAMES {
            assert_eq!(KeyScript::parse(n).unwrap().next_key(), Some(*c));
        }
    }
}
