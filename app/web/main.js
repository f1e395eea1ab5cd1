// Loads the app's WebAssembly and starts it on the page's canvas.
import init, { start, test_nodes, test_state, test_frames } from "./mimicgen_web.js";

const loading = document.getElementById("loading");
try {
  await init();
  start("app");
  loading.remove();
  // For browser tests (pages opened with ?testhook): the widgets and the app's state.
  window.mimicgen = {
    nodes: () => JSON.parse(test_nodes() || "[]"),
    state: () => JSON.parse(test_state() || "null"),
    frames: () => JSON.parse(test_frames() || "[]"),
  };
} catch (e) {
  loading.textContent = "mimicgen could not start: " + e;
  throw e;
}
