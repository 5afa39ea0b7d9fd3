//! Where relative file names are looked up: Mitsuba's `FileResolver`.
//!
//! A scene's relative file names (meshes, textures, `<include>`d files) are
//! tried against a list of folders, in order, and the first one that holds
//! the file wins:
//!
//! 1. the folders given by `<path value="…"/>`, the one declared last first
//!    (each `<path>` is *prepended*, as in Mitsuba);
//! 2. the folder of the scene file that was loaded (the top-level one, also
//!    for names written in included files);
//! 3. the current working directory (the name as written).
//!
//! Mitsuba 3.9 tries the working directory before the scene's folder; Snell
//! tries the scene's folder first, so a scene does not change meaning with the
//! directory it is rendered from. The two orders differ only when both
//! folders hold a file of the same name.
//!
//! A `<path>` value that is relative is taken relative to the folder of the
//! file that contains the `<path>` element, or, if no such folder exists, is
//! itself resolved against the search folders (as Mitsuba does). It must
//! name an existing folder.
//!
//! ```xml
//! <scene version="3.0.0">
//!     <path value="../../common"/>
//!     <shape type="ply"><string name="filename" value="meshes/bunny.ply"/></shape>
//! </scene>
//! ```
//!
//! Meshes and textures are opened after the whole document was parsed, so
//! every `<path>` of the document applies to them; an `<include>` is opened
//! while parsing, so only the `<path>` elements before it apply.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The search folders of one scene document and the files it includes
/// (shared by all of them).
#[derive(Debug, Default)]
pub struct SearchPaths {
    /// `<path>` folders, the last declared first.
    prepended: Mutex<Vec<PathBuf>>,
    /// The folder of the top-level scene file.
    scene_dir: PathBuf,
}

impl SearchPaths {
    /// The search folders of a scene loaded from `scene_file`.
    pub fn for_scene(scene_file: &Path) -> SearchPaths {
        SearchPaths { prepended: Mutex::new(vec![]), scene_dir: folder_of(scene_file) }
    }

    /// Adds a folder in front of the others (Mitsuba's `<path>`).
    pub fn prepend(&self, folder: PathBuf) {
        if let Ok(mut v) = self.prepended.lock() {
            v.insert(0, folder);
        }
    }

    /// The folders tried, in order (the last entry is the working directory).
    pub fn folders(&self) -> Vec<PathBuf> {
        let mut out: Vec<PathBuf> = self.prepended.lock().map(|v| v.clone()).unwrap_or_default();
        out.push(self.scene_dir.clone());
        out.push(PathBuf::from("."));
        out
    }

    /// The first existing file `name` in the search folders, or the folders
    /// that were searched in vain. An absolute name is returned as it is if
    /// it exists.
    pub fn resolve(&self, name: &str) -> Result<PathBuf, Vec<PathBuf>> {
        let p = Path::new(name);
        if p.is_absolute() {
            return if p.exists() { Ok(p.to_path_buf()) } else { Err(vec![]) };
        }
        let folders = self.folders();
        for f in &folders {
            let candidate = if f == Path::new(".") { p.to_path_buf() } else { f.join(p) };
            if candidate.exists() {
                return Ok(candidate);
            }
        }
        Err(folders)
    }

    /// Where `name` is read from: the first folder that holds it, else the
    /// scene's folder joined with it (so that the error names a plausible path).
    pub fn resolve_or_default(&self, name: &str) -> PathBuf {
        self.resolve(name).unwrap_or_else(|_| {
            let p = Path::new(name);
            if p.is_absolute() { p.to_path_buf() } else { self.scene_dir.join(p) }
        })
    }

    /// "looked for NAME in: a, b, c" (help text for a file that was not found),
    /// or `None` if the file exists.
    pub fn not_found_help(&self, name: &str) -> Option<String> {
        match self.resolve(name) {
            Ok(_) => None,
            Err(folders) if folders.is_empty() => Some(format!("the file {name} does not exist")),
            Err(folders) => {
                let list: Vec<String> = folders.iter().map(|f| format!("\"{}\"", f.display())).collect();
                Some(format!(
                    "looked for \"{name}\" in these folders, in order: {} (add a folder with <path value=\"…\"/>)",
                    list.join(", ")
                ))
            }
        }
    }
}

/// The folder that holds `file` ("." for a bare file name).
pub fn folder_of(file: &Path) -> PathBuf {
    match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn later_paths_are_tried_first_then_the_scene_folder() {
        let root = std::env::temp_dir().join(format!("snell-search-{}", std::process::id()));
        let (a, b, scene) = (root.join("a"), root.join("b"), root.join("scene"));
        for d in [&a, &b, &scene] {
            std::fs::create_dir_all(d).unwrap();
        }
        std::fs::write(a.join("x.txt"), "a").unwrap();
        std::fs::write(b.join("x.txt"), "b").unwrap();
        std::fs::write(scene.join("x.txt"), "s").unwrap();
        std::fs::write(scene.join("y.txt"), "s").unwrap();
        let s = SearchPaths::for_scene(&scene.join("s.xml"));
        assert_eq!(s.resolve("x.txt").unwrap(), scene.join("x.txt"));
        s.prepend(a.clone());
        s.prepend(b.clone());
        assert_eq!(s.resolve("x.txt").unwrap(), b.join("x.txt"));
        assert_eq!(s.resolve("y.txt").unwrap(), scene.join("y.txt"));
        let err = s.resolve("z.txt").unwrap_err();
        assert_eq!(err, vec![b.clone(), a.clone(), scene.clone(), PathBuf::from(".")]);
        let help = s.not_found_help("z.txt").unwrap();
        assert!(help.contains(&b.display().to_string()) && help.contains(&scene.display().to_string()), "{help}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
