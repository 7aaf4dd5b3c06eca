// Build of the air-situation display (issue 11 item 4): the bundle goes into the Python package so that
// `pip install` needs no node; pyproject's package-data covers static/* and static/assets/* only.
import { defineConfig } from "vite";

export default defineConfig({
  base: "./",
  build: {
    outDir: "../src/skytrack/service/static",
    assetsDir: "assets",
    emptyOutDir: true,
    // the basemap stays a separate JSON asset fetched from the same server, never inlined into the script
    assetsInlineLimit: 0,
    sourcemap: false,
    target: "es2020",
  },
});
