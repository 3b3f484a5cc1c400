// Opens the viewer in headless Chromium, shows image NAME, hovers pixel (X, Y) and prints what the page plotted
// as JSON: {"pixel": "x,y", "points": [[nm, value], ...]}. Optionally writes a screenshot.
// Usage: node hover.mjs URL NAME X Y [SCREENSHOT.png]
import { launch } from "./launch.mjs";

const [url, name, xs, ys, shot] = process.argv.slice(2);
const x = Number(xs), y = Number(ys);
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(`${url}#images=${encodeURIComponent(name)}`);
  const img = page.locator("#picture");
  await page.waitForSelector("#picture[data-loaded='1']", { timeout: 20000 });
  const box = await img.boundingBox();
  const natural = await img.evaluate((e) => [e.naturalWidth, e.naturalHeight]);
  await page.mouse.move(box.x + ((x + 0.5) * box.width) / natural[0], box.y + ((y + 0.5) * box.height) / natural[1]);
  await page.waitForSelector(`#spectrum[data-pixel='${x},${y}']`, { timeout: 20000 });
  const points = await page.$$eval("#spectrum g.spectrum circle", (cs) =>
    cs.map((c) => [Number(c.getAttribute("data-nm")), Number(c.getAttribute("data-value"))]));
  if (shot) await page.screenshot({ path: shot, fullPage: true });
  if (errors.length) throw new Error(`the page threw: ${errors.join("; ")}`);
  console.log(JSON.stringify({ pixel: `${x},${y}`, points }));
} finally {
  await browser.close();
}
