//! Scene errors that say where: file, line and column, the offending line
//! with a caret under the column, and (where it helps) the valid choices.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A loaded source file, kept so that errors can quote the offending line.
#[derive(Debug)]
pub struct SourceFile {
    pub path: PathBuf,
    pub text: String,
    /// The folders where relative file names in this file are looked up
    /// (shared by a scene file and the files it includes).
    pub search: Arc<super::search::SearchPaths>,
    /// Byte offset of the start of each line, built once so that a location
    /// costs a binary search (O(log n)) instead of a scan of the file.
    line_starts: Vec<usize>,
}

impl SourceFile {
    /// A file of its own scene: names resolve against its folder.
    pub fn new(path: PathBuf, text: String) -> SourceFile {
        let search = Arc::new(super::search::SearchPaths::for_scene(&path));
        SourceFile::with_search(path, text, search)
    }

    /// A file whose relative names resolve through `search` (an included
    /// file shares its document's search folders).
    pub fn with_search(path: PathBuf, text: String, search: Arc<super::search::SearchPaths>) -> SourceFile {
        let mut line_starts = vec![0];
        line_starts.extend(text.bytes().enumerate().filter(|&(_, b)| b == b'\n').map(|(i, _)| i + 1));
        SourceFile { path, text, search, line_starts }
    }

    /// The 0-based line holding byte `byte`, and that line's first byte.
    fn line_of(&self, byte: usize) -> (usize, usize) {
        let line = self.line_starts.partition_point(|&s| s <= byte).saturating_sub(1);
        (line, self.line_starts[line])
    }

    /// The text of 1-based line `line`, without its line break.
    pub fn line_text(&self, line: u32) -> &str {
        let Some(&start) = self.line_starts.get(line.saturating_sub(1) as usize) else { return "" };
        let end = self.line_starts.get(line as usize).map_or(self.text.len(), |&e| e - 1);
        self.text.get(start..end.max(start)).unwrap_or("").trim_end_matches('\r')
    }
}

#[derive(Clone, Debug)]
pub struct Location {
    pub file: Arc<SourceFile>,
    /// 1-based line and column (column in characters).
    pub line: u32,
    pub col: u32,
}

impl Location {
    pub fn new(file: &Arc<SourceFile>, line: u32, col: u32) -> Location {
        Location { file: file.clone(), line, col }
    }

    /// The location of a byte offset in the file.
    pub fn at_byte(file: &Arc<SourceFile>, byte: usize) -> Location {
        let mut byte = byte.min(file.text.len());
        while !file.text.is_char_boundary(byte) {
            byte -= 1;
        }
        let (line, line_start) = file.line_of(byte);
        let col = file.text[line_start..byte].chars().count() as u32 + 1;
        Location::new(file, line as u32 + 1, col)
    }

    pub fn source_line(&self) -> &str {
        self.file.line_text(self.line)
    }
}

#[derive(Debug, Clone)]
pub struct SceneError {
    pub message: String,
    pub location: Option<Location>,
    /// A path for errors about a file that could not be read at all.
    pub path: Option<PathBuf>,
    pub help: Option<String>,
}

pub type Result<T, E = SceneError> = std::result::Result<T, E>;

impl SceneError {
    pub fn at(location: &Location, message: impl Into<String>) -> SceneError {
        SceneError { message: message.into(), location: Some(location.clone()), path: None, help: None }
    }

    pub fn file(path: &Path, message: impl Into<String>) -> SceneError {
        SceneError { message: message.into(), location: None, path: Some(path.to_path_buf()), help: None }
    }

    pub fn with_help(mut self, help: impl Into<String>) -> SceneError {
        self.help = Some(help.into());
        self
    }

    /// "valid choices are: a, b, c" as help text.
    pub fn with_choices(self, choices: &[&str]) -> SceneError {
        self.with_help(format!("valid choices are: {}", choices.join(", ")))
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "error: {}", self.message)?;
        if let Some(loc) = &self.location {
            let gutter = loc.line.to_string().len();
            let pad = " ".repeat(gutter);
            writeln!(f, "{pad}--> {}:{}:{}", loc.file.path.display(), loc.line, loc.col)?;
            writeln!(f, "{pad} |")?;
            let line = loc.source_line().replace('\t', " ");
            writeln!(f, "{} | {}", loc.line, line)?;
            let caret_pad = " ".repeat(loc.col.saturating_sub(1) as usize);
            write!(f, "{pad} | {caret_pad}^")?;
        } else if let Some(p) = &self.path {
            write!(f, "  --> {}", p.display())?;
        }
        if let Some(help) = &self.help {
            write!(f, "\n  = help: {help}")?;
        }
        Ok(())
    }
}

impl std::error::Error for SceneError {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cached line table answers like a scan from the start, for
    /// every byte, with two files asked about in turn.
    #[test]
    fn locations_match_a_scan_from_the_start() {
        let a = Arc::new(SourceFile::new("a.xml".into(), "<scene>\n  <bsdf/>\n\n é<x/>\nlast".into()));
        let b = Arc::new(SourceFile::new("b.xml".into(), "\n\nxy\n".into()));
        for _ in 0..2 {
            for f in [&a, &b] {
                for (byte, _) in f.text.char_indices().chain([(f.text.len(), ' ')]) {
                    let before = &f.text[..byte];
                    let line = before.matches('\n').count() as u32 + 1;
                    let col = before[before.rfind('\n').map_or(0, |i| i + 1)..].chars().count() as u32 + 1;
                    let loc = Location::at_byte(f, byte);
                    assert_eq!((loc.line, loc.col), (line, col), "{} byte {byte}", f.path.display());
                }
            }
        }
    }

    #[test]
    fn display_quotes_the_line_with_a_caret() {
        let file = Arc::new(SourceFile::new("a.xml".into(), "<scene>\n  <bsdf type=\"x\"/>\n".into()));
        let loc = Location::at_byte(&file, file.text.find("<bsdf").unwrap());
        assert_eq!((loc.line, loc.col), (2, 3));
        let e = SceneError::at(&loc, "unknown bsdf \"x\"").with_choices(&["diffuse"]);
        let s = e.to_string();
        assert!(s.contains("a.xml:2:3"), "{s}");
        assert!(s.contains("2 |   <bsdf type=\"x\"/>"), "{s}");
        assert!(s.contains("  |   ^"), "{s}");
        assert!(s.contains("valid choices are: diffuse"), "{s}");
    }

    #[test]
    fn line_index_matches_a_scan() {
        let text = "a\r\nbc\n\nλx\nlast";
        let file = Arc::new(SourceFile::new("t.xml".into(), text.into()));
        for byte in 0..=text.len() + 3 {
            let b = byte.min(text.len());
            if !text.is_char_boundary(b) {
                continue;
            }
            let before = &text[..b];
            let line = before.matches('\n').count() as u32 + 1;
            let col = before[before.rfind('\n').map_or(0, |i| i + 1)..].chars().count() as u32 + 1;
            let loc = Location::at_byte(&file, byte);
            assert_eq!((loc.line, loc.col), (line, col), "byte {byte}");
            assert_eq!(loc.source_line(), text.lines().nth(line as usize - 1).unwrap_or(""));
        }
        assert_eq!(file.line_text(99), "");
    }
}
