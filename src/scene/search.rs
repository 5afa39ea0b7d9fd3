//! Where relative file names are looked up: Mitsuba 3.9's `FileResolver`.
//!
//! A scene's relative file names are tried against a list of folders, in
//! order, and the first one that holds the file wins. Meshes and textures
//! (opened by the loader, after the whole document was parsed) use the
//! folders of the top-level scene file:
//!
//! 1. the folders given by its `<path value="…"/>` elements, the one declared
//!    last first (each `<path>` is *prepended*, as in Mitsuba);
//! 2. the folder of the scene file;
//! 3. the current working directory (the name as written).
//!
//! (As in Mitsuba 3.9, a `<path>` inside an included file does not apply to
//! meshes and textures, also not to those of the included file.)
//!
//! `<include filename>` and `<path value>` are resolved while parsing, with
//! the folders of the file that contains them: its own `<path>`s so far
//! (last first), its own folder, then the folders of the file that included
//! it (as they were at the `<include>`), and the working directory last. So
//! an `<include>` inside an included file looks in that file's folder
//! first, then in the including file's, up to the scene's folder. A `<path>`
//! must name an existing folder.
//!
//! ```xml
//! <scene version="3.0.0">
//!     <path value="../../common"/>
//!     <shape type="ply"><string name="filename" value="meshes/bunny.ply"/></shape>
//! </scene>
//! ```

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
