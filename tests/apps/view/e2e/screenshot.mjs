// Opens the viewer at URL + HASH (e.g. "#grids=name"), waits until the page has settled, writes a screenshot.
// Usage: node screenshot.mjs URL OUT.png [HASH]
import { launch } from "./launch.mjs";

const [url, out, hash] = process.argv.slice(2);
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  await page.goto(url + (hash || ""), { waitUntil: "networkidle", timeout: 60000 });
  await page.screenshot({ path: out, fullPage: true });
} finally {
  await browser.close();
}
