//! Hot reload: the shader folder given on the command line, watched, and its edited stages rebuilt between frames.
use super::{State, ViewOptions};
use crate::error::Error;
use crate::render::Renderer;
use crate::shaders::{ShaderDir, ShaderWatcher};
use std::time::Duration;

/// The shader folder `options` names (if any): its stages replace the built-in ones, and it is watched for edits.
pub(super) fn watch_shaders(
    renderer: &mut Renderer,
    options: &ViewOptions,
) -> Result<Option<(ShaderDir, ShaderWatcher)>, Error> {
    Ok(match &options.shader_dir {
        Some(dir) => {
            let dir = ShaderDir::open(dir)?;
            let used = renderer.load_shaders(&dir, None)?;
            eprintln!("using {} from {}", used.join(", "), dir.root().display());
            let watcher = ShaderWatcher::new(&dir)?;
            Some((dir, watcher))
        }
        None => None,
    })
}

impl State {
    pub(super) fn reload_shaders(&mut self) -> Result<(), Error> {
        let Some((dir, watcher)) = &self.shaders else {
            return Ok(());
        };
        let changed = watcher.changed(Duration::ZERO);
        let stale = dir.affected(&changed);
        if stale.is_empty() {
            return Ok(());
        }
        match self.renderer.load_shaders(dir, Some(&stale)) {
            Ok(rebuilt) => {
                eprintln!("rebuilt {}", rebuilt.join(", "));
                self.reset()
            }
            Err(e) => {
                // The previous pipelines keep running, and so does the accumulation.
                eprintln!("error: {e}\nkeeping the previous pipelines");
                Ok(())
            }
        }
    }
}
