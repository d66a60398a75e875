//! Reading OBJ and MTL text a line at a time: the line tap that tells the
//! loader which line it is on, and the second scans that locate a bad
//! vertex or face after tobj rejected a file (error path only).

use super::*;

// ---------------------------------------------------------------------------
// The line tap
// ---------------------------------------------------------------------------

/// A `BufRead` adapter that hands its reader one line at a time, so that it
/// knows which line the consumer is on. Each line is made valid UTF-8
/// (lossily, counted) and passed to a hook that may inspect or rewrite it,
/// or stop the reading with a message.
pub(super) struct LineTap<R, F> {
    pub(super) inner: R,
    pub(super) hook: F,
    pub(super) buf: Vec<u8>,
    pub(super) pos: usize,
    pub(super) line: usize,
    pub(super) halted: Option<(usize, String)>,
    pub(super) io_error: Option<io::Error>,
    pub(super) lossy_lines: u64,
    pub(super) first_lossy_line: usize,
}

/// What a tap knows after its consumer stopped.
pub(super) struct TapOutcome {
    /// 1-based number of the last line handed out (0 if none).
    pub(super) line: usize,
    /// The text of that line.
    pub(super) last_line: String,
    /// The line and message with which the hook stopped the reading.
    pub(super) halted: Option<(usize, String)>,
    /// An error of the underlying reader.
    pub(super) io_error: Option<io::Error>,
    pub(super) lossy_lines: u64,
    pub(super) first_lossy_line: usize,
}

impl<R: BufRead, F: FnMut(usize, &mut Vec<u8>) -> Result<(), String>> LineTap<R, F> {
    pub(super) fn new(inner: R, hook: F) -> Self {
        LineTap {
            inner,
            hook,
            buf: Vec::new(),
            pos: 0,
            line: 0,
            halted: None,
            io_error: None,
            lossy_lines: 0,
            first_lossy_line: 0,
        }
    }

    pub(super) fn finish(self) -> TapOutcome {
        TapOutcome {
            line: self.line,
            last_line: String::from_utf8_lossy(&self.buf).into_owned(),
            halted: self.halted,
            io_error: self.io_error,
            lossy_lines: self.lossy_lines,
            first_lossy_line: self.first_lossy_line,
        }
    }
}

impl<R: BufRead, F: FnMut(usize, &mut Vec<u8>) -> Result<(), String>> BufRead for LineTap<R, F> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.pos >= self.buf.len() {
            if self.halted.is_some() || self.io_error.is_some() {
                return Err(io::Error::other("reading was stopped"));
            }
            self.buf.clear();
            self.pos = 0;
            match self.inner.read_until(b'\n', &mut self.buf) {
                Ok(0) => return Ok(&[]),
                Ok(_) => {}
                Err(e) => {
                    let copy = io::Error::new(e.kind(), e.to_string());
                    self.io_error = Some(e);
                    return Err(copy);
                }
            }
            self.line += 1;
            // A UTF-8 byte order mark would glue itself to the first keyword.
            if self.line == 1 && self.buf.starts_with(b"\xEF\xBB\xBF") {
                self.buf.drain(..3);
            }
            if std::str::from_utf8(&self.buf).is_err() {
                self.buf = String::from_utf8_lossy(&self.buf).into_owned().into_bytes();
                if self.lossy_lines == 0 {
                    self.first_lossy_line = self.line;
                }
                self.lossy_lines += 1;
            }
            if let Err(message) = (self.hook)(self.line, &mut self.buf) {
                self.halted = Some((self.line, message));
                return Err(io::Error::other("reading was stopped"));
            }
        }
        Ok(&self.buf[self.pos..])
    }

    fn consume(&mut self, amount: usize) {
        self.pos = (self.pos + amount).min(self.buf.len());
    }
}

impl<R: BufRead, F: FnMut(usize, &mut Vec<u8>) -> Result<(), String>> Read for LineTap<R, F> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let available = self.fill_buf()?;
        let n = available.len().min(out.len());
        out[..n].copy_from_slice(&available[..n]);
        self.consume(n);
        Ok(n)
    }
}

// ---------------------------------------------------------------------------
// Second scans (error path only)
// ---------------------------------------------------------------------------

/// Streams the lines of `path` (lossily decoded) to `f` with their 1-based
/// numbers until `f` returns `Some`. Never holds more than one line.
pub(super) fn scan_lines<T>(
    path: &Path,
    mut f: impl FnMut(usize, &str) -> Option<T>,
) -> io::Result<Option<T>> {
    let mut reader = BufReader::with_capacity(1 << 16, File::open(path)?);
    let mut buf = Vec::new();
    let mut line_no = 0;
    loop {
        buf.clear();
        if reader.read_until(b'\n', &mut buf)? == 0 {
            return Ok(None);
        }
        line_no += 1;
        let text = String::from_utf8_lossy(&buf);
        if let Some(found) = f(line_no, strip_newline(&text)) {
            return Ok(Some(found));
        }
    }
}

/// Why a coordinate is rejected, if it is.
pub(super) fn coordinate_problem(value: f32) -> Option<&'static str> {
    if !value.is_finite() {
        Some("is not finite")
    } else if value.abs() > MAX_ABS_COORDINATE {
        Some("exceeds the limit ±1e8 (f32 voxel grid coordinates lose meaning beyond it)")
    } else {
        None
    }
}

/// Finds the first `v` line whose coordinates (after tobj's optional `w`
/// division) are non-finite or huge.
pub(super) fn locate_bad_vertex(path: &Path) -> Option<SceneError> {
    let mut vertex = 0usize;
    let found = scan_lines(path, |line_no, line| {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            return None;
        }
        vertex += 1;
        let mut p = [0.0f32; 3];
        for c in &mut p {
            *c = words.next()?.parse().ok()?;
        }
        if let (Some(w), None) = (words.next(), words.next()) {
            let w: f32 = w.parse().ok()?;
            p = p.map(|c| c / w);
        }
        let (axis, value, problem) = (0..3)
            .find_map(|k| coordinate_problem(p[k]).map(|why| (["x", "y", "z"][k], p[k], why)))?;
        Some((
            line_no,
            format!(
                "vertex {vertex}: coordinate {axis} = {value} {problem}: `{}`",
                clip(line)
            ),
        ))
    });
    let (line, message) = found.ok()??;
    Some(SceneError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    })
}

/// Finds the first `f` line with an index outside the file's records (or
/// no vertex at all). Two streaming passes: the first counts the records,
/// the second checks every face against those totals. A face that refers
/// to a record defined only later is reported when nothing worse exists.
pub(super) fn locate_bad_face(path: &Path) -> Option<SceneError> {
    let mut totals = [0usize; 3];
    scan_lines(path, |_, line| {
        match line.split_whitespace().next() {
            Some("v") => totals[0] += 1,
            Some("vt") => totals[1] += 1,
            Some("vn") => totals[2] += 1,
            _ => {}
        }
        None::<()>
    })
    .ok()?;

    let mut counts = [0usize; 3];
    let mut forward: Option<(usize, String)> = None;
    let found = scan_lines(path, |line_no, line| {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f") => {
                let tokens: Vec<&str> = words.collect();
                if tokens.is_empty() {
                    return Some((line_no, format!("face without vertices: `{}`", clip(line))));
                }
                for token in tokens {
                    for (kind, part) in token.split('/').take(3).enumerate() {
                        // tobj ignores texcoord and normal indices when the
                        // file has no such records.
                        if part.is_empty() || (kind > 0 && totals[kind] == 0) {
                            continue;
                        }
                        let Ok(x) = part.parse::<i64>() else { continue };
                        let what = INDEX_KINDS[kind];
                        let index = if x < 0 {
                            counts[kind] as i64 + x + 1
                        } else {
                            x
                        };
                        if index < 1 || index > totals[kind] as i64 {
                            return Some((
                                line_no,
                                format!(
                                    "face refers to {what} {x}, but the file defines {} {what}(s): `{}`",
                                    totals[kind],
                                    clip(line)
                                ),
                            ));
                        }
                        if index > counts[kind] as i64 && forward.is_none() {
                            forward = Some((
                                line_no,
                                format!(
                                    "face refers to {what} {x} before it is defined (only {} \
                                     precede this line): `{}`",
                                    counts[kind],
                                    clip(line)
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
        None
    })
    .ok()?;
    let (line, message) = found.or(forward)?;
    Some(SceneError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    })
}
