// Opens the viewer at URL + HASH (e.g. "#grids=name"), waits until the page has settled, writes a screenshot.
// Usage: node screenshot.mjs URL OUT.png [HASH]
import { chromium } from "playwright-core";

const [url, out, hash] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-quic",
         "--no-first-run", "--disable-component-update", "--disable-sync"],
});
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  await page.goto(url + (hash || ""), { waitUntil: "networkidle", timeout: 60000 });
  await page.screenshot({ path: out, fullPage: true });
} finally {
  await browser.close();
}
