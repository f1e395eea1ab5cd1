// Starts the Rerun web viewer on this page's canvas, reading the recordings named by the page's
// `url` query (the server's gRPC proxy, on this page's own origin), and keeps its WebHandle as
// window._handle: the app in the parent page moves the viewer's time through it, and reads it back.
"use strict";
(async () => {
  const status = document.getElementById("status");
  try {
    await wasm_bindgen({ module_or_path: "re_viewer_bg.wasm" });
    const query = new URLSearchParams(location.search);
    const handle = new wasm_bindgen.WebHandle({
      url: query.getAll("url"),
      hide_welcome_screen: true,
      enable_history: false,
      notebook: false,
      persist: false,
    });
    await handle.start(document.getElementById("viewer_canvas"));
    window._handle = handle;
    status.remove();
    const panicked = () => {
      if (handle.has_panicked()) {
        status.textContent = "the 3D viewer crashed: " + handle.panic_message();
        document.body.appendChild(status);
      } else {
        setTimeout(panicked, 1000);
      }
    };
    panicked();
  } catch (e) {
    status.textContent = "the 3D viewer could not start: " + e;
    throw e;
  }
})();
