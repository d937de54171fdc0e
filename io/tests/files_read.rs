//! Once a program asks for it
//! ([`output::protect_files_read`]), every file a reader opened is an input that no output
//! replaces, in any spelling, whatever the policy's `overwrite` says. Its own test binary: the
//! record is process-wide, and the unit tests of the crate run without it.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use animcodec_io::formats::{self, ReadOptions};
use animcodec_io::output::{self, commit_all, OutputPolicy, PendingFile};

/// A scratch directory removed on drop.
struct Dir(PathBuf);

impl Dir {
    fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("animcodec-files-read-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn every_file_a_reader_opened_is_refused_as_an_output() {
    output::protect_files_read();
    let dir = Dir::new("gltf");
    // A .gltf with an external buffer: the synthetic flag written as a .glb, split.
    let anim = animcodec_synth::by_name("flag", animcodec_synth::SynthSize::Small).unwrap();
    let glb_path = dir.path("flag.glb");
    formats::write_animation(&glb_path, &anim).unwrap();
    let glb = std::fs::read(&glb_path).unwrap();
    let u32_at = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = &glb[28 + json_len..28 + json_len + u32_at(20 + json_len)];
    json["buffers"][0]["uri"] = "flag.bin".into();
    std::fs::write(dir.path("flag.bin"), bin).unwrap();
    std::fs::write(dir.path("flag.gltf"), serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::hard_link(dir.path("flag.bin"), dir.path("hard.bin")).unwrap();
    std::os::unix::fs::symlink(dir.path("flag.bin"), dir.path("link.bin")).unwrap();

    // Nothing read yet: the buffer may be replaced.
    let force = OutputPolicy::new(true);
    force.check(&dir.path("flag.bin")).unwrap();
    formats::read_animation(&dir.path("flag.gltf"), &ReadOptions::default()).unwrap();
    let spellings = [
        dir.path("flag.bin"),
        dir.0.join(".").join("flag.bin"),
        dir.path("hard.bin"),
        dir.path("link.bin"),
        dir.path("flag.gltf"),
    ];
    for p in &spellings {
        let e = force.check(p).unwrap_err().to_string();
        assert!(e.contains("also an input") && e.contains("even with --force"), "{}: {e}", p.display());
    }
    let e = force.check(&dir.path("flag.bin")).unwrap_err().to_string();
    assert!(e.contains("external buffer 'flag.bin' of") && e.contains("flag.gltf"), "{e}");
    // The last guard: a pending file committed over it (whatever path led there) is refused,
    // and nothing is renamed.
    let before = std::fs::read(dir.path("flag.bin")).unwrap();
    let mut other = PendingFile::new(&dir.path("other.txt")).unwrap();
    other.write_all(b"x").unwrap();
    let mut file = PendingFile::new(&dir.path("hard.bin")).unwrap();
    file.write_all(b"not geometry").unwrap();
    let e = commit_all(vec![other, file], &[]).unwrap_err().to_string();
    assert!(e.contains("hard.bin") && e.contains("also an input"), "{e}");
    assert_eq!(std::fs::read(dir.path("flag.bin")).unwrap(), before);
    assert!(!Path::new(&dir.path("other.txt")).exists(), "no output is renamed when one is refused");
    // Nor removed as a stale file.
    let e = commit_all(Vec::new(), &[dir.path("link.bin")]).unwrap_err().to_string();
    assert!(e.contains("also an input"), "{e}");
    assert!(dir.path("flag.bin").exists());
    // Other files are written as before.
    force.write(&dir.path("fresh.bin"), b"ok").unwrap();

    // A cache's topology OBJ, named as such.
    let cache = dir.path("c.pc2");
    formats::write_animation(&cache, &anim).unwrap();
    formats::read_animation(&cache, &ReadOptions::default()).unwrap();
    let e = OutputPolicy::new(true).check(&dir.path("c.obj")).unwrap_err().to_string();
    assert!(e.contains("topology OBJ"), "{e}");
}
