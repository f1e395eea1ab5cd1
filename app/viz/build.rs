//! Embeds the directory of libmujoco.so (from `MUJOCO_DYNAMIC_LINK_DIR`, set by .cargo/config.toml)
//! as an rpath, so binaries and tests find the library with no `LD_LIBRARY_PATH`.
fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    if let Ok(dir) = std::env::var("MUJOCO_DYNAMIC_LINK_DIR") {
        println!("cargo::rustc-link-arg=-Wl,-rpath,{dir}");
    }
}
