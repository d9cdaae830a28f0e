#!/usr/bin/env node
// Screenshot of an avsim bag in Foxglove Studio with docs/foxglove_layout.json, made headless:
//
//   cd docs/foxglove_screenshot && npm ci
//   node screenshot.js BAG.mcap OUT.png [--time SECONDS] [--layout FILE] [--size 1600x900]
//                      [--settle SECONDS] [--chromium PATH]
//
// Foxglove Studio here is @foxglove/studio-base 1.48.0 (MPL-2.0), the last build of Foxglove's
// app that was published to npm: a prebuilt web bundle of the whole app. This script serves it,
// with React 17 and the bag, from a local HTTP server on 127.0.0.1, opens it in Debian's Chromium
// (headless, WebGL on SwiftShader) through puppeteer-core, loads the bag as a remote file (HTTP
// range requests) and the layout from memory, seeks to --time, waits --settle seconds for the
// panels to draw, and saves the page as a PNG (written beside OUT and renamed over it).
//
// One change to the layout, made here in memory and nowhere else: 1.48's "Image" panel predates
// the `imageMode` settings the layout's image panels use (it draws the frame tree instead of the
// image), so each Image panel is shown with 1.48's older image panel ("ImageViewPanel"), on the
// same image topic with the same ImageMarker topic drawn over it. Every other panel is the
// layout's own. Current Foxglove reads the layout as it is.
//
// Bad input (no bag, an unwritable OUT, no Chromium, a bad --time) is one line and exit 2, before
// the browser starts. Nothing is fetched from outside this machine while it runs.
"use strict";

const fs = require("fs");
const http = require("http");
const path = require("path");

const HERE = __dirname;
const DEFAULT_LAYOUT = path.join(HERE, "..", "foxglove_layout.json");
const ASSETS = path.join(HERE, "node_modules", "@foxglove", "studio-base", "assets");
const REACT = path.join(HERE, "node_modules", "react", "umd", "react.production.min.js");
const REACT_DOM = path.join(HERE, "node_modules", "react-dom", "umd", "react-dom.production.min.js");
const CHROMIUM_CANDIDATES = ["/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"];
const LAYOUT_ID = "avsim";

class UsageError extends Error {}

function parseArgs(argv) {
  const options = { time: null, layout: DEFAULT_LAYOUT, size: "1600x900", settle: 20, chromium: null };
  const positional = [];
  for (let i = 0; i < argv.length; i++) {
    const arg = argv[i];
    if (!arg.startsWith("--")) { positional.push(arg); continue; }
    const key = arg.slice(2);
    if (!(key in options)) throw new UsageError(`unknown option ${arg}; options: --time, --layout, --size, --settle, --chromium`);
    if (i + 1 >= argv.length) throw new UsageError(`${arg} needs a value`);
    options[key] = argv[++i];
  }
  if (positional.length !== 2) throw new UsageError("usage: node screenshot.js BAG.mcap OUT.png [--time SECONDS] [--layout FILE] [--size WxH] [--settle SECONDS] [--chromium PATH]");
  [options.bag, options.out] = positional;
  return options;
}

function checkInputs(options) {
  if (!fs.existsSync(options.bag) || !fs.statSync(options.bag).isFile()) throw new UsageError(`bag ${options.bag} is not a file; pass an .mcap written by avsim run --mcap`);
  const head = Buffer.alloc(8);
  const fd = fs.openSync(options.bag, "r");
  fs.readSync(fd, head, 0, 8, 0);
  fs.closeSync(fd);
  if (!head.equals(Buffer.from([0x89, 0x4d, 0x43, 0x41, 0x50, 0x30, 0x0d, 0x0a]))) throw new UsageError(`bag ${options.bag} is not an MCAP file (no MCAP magic); pass an .mcap written by avsim run --mcap`);
  if (!options.out.toLowerCase().endsWith(".png")) throw new UsageError(`OUT must end in .png, got ${options.out}`);
  const outDir = path.dirname(path.resolve(options.out));
  // A file is tried, not the permission bits, which say nothing for root.
  const probe = path.join(outDir, `.foxglove-write-test-${process.pid}`);
  try { fs.writeFileSync(probe, ""); fs.unlinkSync(probe); } catch { throw new UsageError(`cannot write ${options.out}: ${outDir} is not a writable folder; give another path`); }
  if (fs.existsSync(options.out) && !fs.statSync(options.out).isFile()) throw new UsageError(`${options.out} exists and is not a file; give another path`);
  if (!fs.existsSync(options.layout)) throw new UsageError(`layout ${options.layout} does not exist`);
  if (options.time !== null && !(Number(options.time) >= 0)) throw new UsageError(`--time needs seconds of simulated time >= 0, got ${options.time}`);
  if (!/^\d+x\d+$/.test(options.size)) throw new UsageError(`--size needs WIDTHxHEIGHT in pixels, got ${options.size}`);
  if (!(Number(options.settle) > 0)) throw new UsageError(`--settle needs seconds > 0, got ${options.settle}`);
  if (!fs.existsSync(path.join(ASSETS, "index.js"))) throw new UsageError(`Foxglove Studio is not installed here; run npm ci in ${HERE}`);
  options.chromium = options.chromium ?? CHROMIUM_CANDIDATES.find((p) => fs.existsSync(p));
  if (!options.chromium || !fs.existsSync(options.chromium)) throw new UsageError("no Chromium found; install Debian's (apt-get install chromium) or pass --chromium PATH");
}

// The layout as 1.48 shows it: each "Image" panel as an "ImageViewPanel" on the same topics (see the top).
function layoutFor148(layout) {
  const configs = {};
  const renamed = {};
  for (const [id, config] of Object.entries(layout.configById)) {
    if (!id.startsWith("Image!")) { configs[id] = config; continue; }
    const mode = config.imageMode ?? {};
    const newId = `ImageViewPanel!${id.slice("Image!".length)}`;
    renamed[id] = newId;
    configs[newId] = {
      cameraTopic: mode.imageTopic,
      enabledMarkerTopics: Object.keys(mode.annotations ?? {}),
      foxglovePanelTitle: config.foxglovePanelTitle,
      mode: "fit",
      zoomPercentage: 100,
      synchronize: false,
    };
  }
  let tree = JSON.stringify(layout.layout);
  for (const [from, to] of Object.entries(renamed)) tree = tree.split(JSON.stringify(from)).join(JSON.stringify(to));
  return { ...layout, configById: configs, layout: JSON.parse(tree) };
}

const PAGE = `<!doctype html><html><head><meta charset="utf-8"><title>avsim bag in Foxglove Studio</title>
<style>html,body,#root{margin:0;width:100%;height:100%}</style></head><body><div id="root"></div>
<script src="/react.js"></script><script src="/react-dom.js"></script>
<script>window["react"] = React; window["react-dom"] = ReactDOM;</script>
<script src="/assets/index.js"></script>
<script>
(async () => {
  await initI18n();
  const data = await (await fetch("/layout.json")).json();
  const layout = {id: "${LAYOUT_ID}", name: "avsim", permission: "CREATOR_WRITE", baseline: {data, savedAt: undefined},
                  working: undefined, syncInfo: undefined};
  const layoutStorage = {list: async () => [layout], get: async (ns, id) => (id === layout.id ? layout : undefined),
                         put: async (ns, l) => l, delete: async () => {}, importLayouts: async () => {}};
  const settings = new Map([["enableNewImagePanel", true], ["hideSignInPrompt", true], ["timezone", "UTC"], ["colorScheme", "dark"]]);
  const appConfiguration = {get: (k) => settings.get(k), set: async (k, v) => { settings.set(k, v); },
                            addChangeListener() {}, removeChangeListener() {}};
  ReactDOM.render(React.createElement(App, {deepLinks: [location.href], appConfiguration, layoutStorage,
    dataSources: [new RemoteDataSourceFactory()], extensionLoaders: [], enableGlobalCss: true}),
    document.getElementById("root"));
})().catch((e) => { document.body.innerText = "page error: " + e; });
</script></body></html>`;

const TYPES = { ".js": "text/javascript", ".wasm": "application/wasm", ".png": "image/png", ".ttf": "font/ttf", ".json": "application/json" };

// Serves the page, React, Foxglove's assets, the layout and the bag (with HTTP range requests).
function serve(options, layoutText) {
  const files = { "/react.js": REACT, "/react-dom.js": REACT_DOM, "/bag.mcap": path.resolve(options.bag) };
  const server = http.createServer((req, res) => {
    const url = new URL(req.url, "http://127.0.0.1");
    if (url.pathname === "/" || url.pathname === "/index.html") { res.writeHead(200, { "Content-Type": "text/html" }); return res.end(PAGE); }
    if (url.pathname === "/layout.json") { res.writeHead(200, { "Content-Type": "application/json" }); return res.end(layoutText); }
    let file = files[url.pathname];
    if (!file && url.pathname.startsWith("/assets/")) {
      const name = path.basename(url.pathname);
      file = path.join(ASSETS, name);
    }
    if (!file || !fs.existsSync(file)) { res.writeHead(404); return res.end(); }
    const size = fs.statSync(file).size;
    const headers = { "Content-Type": TYPES[path.extname(file)] ?? "application/octet-stream", "Accept-Ranges": "bytes", "Access-Control-Allow-Origin": "*" };
    const range = /^bytes=(\d*)-(\d*)$/.exec(req.headers.range ?? "");
    if (!range) { res.writeHead(200, { ...headers, "Content-Length": size }); return req.method === "HEAD" ? res.end() : fs.createReadStream(file).pipe(res); }
    const start = range[1] ? Number(range[1]) : 0;
    const end = Math.min(range[2] ? Number(range[2]) : size - 1, size - 1);
    res.writeHead(206, { ...headers, "Content-Range": `bytes ${start}-${end}/${size}`, "Content-Length": end - start + 1 });
    return req.method === "HEAD" ? res.end() : fs.createReadStream(file, { start, end }).pipe(res);
  });
  return new Promise((resolve) => server.listen(0, "127.0.0.1", () => resolve(server)));
}

function isoTime(seconds) {
  // avsim's stamps are simulated seconds from 0, i.e. from the Unix epoch.
  const ns = BigInt(Math.round(Number(seconds) * 1e9));
  const whole = new Date(Number(ns / 1000000000n) * 1000).toISOString().slice(0, 19);
  return `${whole}.${String(ns % 1000000000n).padStart(9, "0")}Z`;
}

async function main() {
  const options = parseArgs(process.argv.slice(2));
  checkInputs(options);
  const layoutText = JSON.stringify(layoutFor148(JSON.parse(fs.readFileSync(options.layout, "utf8"))));
  const puppeteer = require("puppeteer-core");
  const server = await serve(options, layoutText);
  const [width, height] = options.size.split("x").map(Number);
  const { port } = server.address();
  const query = new URLSearchParams({ ds: "remote-file", "ds.url": `http://127.0.0.1:${port}/bag.mcap`, layoutId: LAYOUT_ID });
  if (options.time !== null) query.set("time", isoTime(options.time));
  const browser = await puppeteer.launch({
    executablePath: options.chromium, headless: "new",
    args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", `--window-size=${width},${height}`],
  });
  const tmp = path.join(path.dirname(path.resolve(options.out)), `.${path.basename(options.out)}.${process.pid}.tmp.png`);
  try {
    const page = await browser.newPage();
    await page.setViewport({ width, height, deviceScaleFactor: 1 });
    page.on("pageerror", (e) => console.error(`foxglove page error: ${String(e).split("\n")[0]}`));
    await page.goto(`http://127.0.0.1:${port}/?${query}`, { waitUntil: "load", timeout: 120000 });
    await new Promise((r) => setTimeout(r, Number(options.settle) * 1000));
    // The data-source sidebar and the 3D panel's first-use tip cover the panels: close both.
    await page.evaluate(() => {
      const sidebar = document.querySelector('button[title="Data source"]');
      if (sidebar) sidebar.click();
    });
    await new Promise((r) => setTimeout(r, 2000));
    await page.evaluate(() => document.querySelectorAll('[role="tooltip"]').forEach((e) => e.remove()));
    await page.screenshot({ path: tmp, type: "png" });
    fs.renameSync(tmp, options.out);
    console.log(`wrote ${options.out} (${fs.statSync(options.out).size} bytes)`);
  } finally {
    if (fs.existsSync(tmp)) fs.unlinkSync(tmp);
    await browser.close();
    server.close();
  }
}

if (require.main === module) {
  main().catch((e) => {
    console.error(e instanceof UsageError ? `error: ${e.message}` : `error: ${String(e).split("\n")[0]}`);
    process.exit(e instanceof UsageError ? 2 : 1);
  });
}

module.exports = { layoutFor148 };
