// Opens the viewer in headless Chromium on grid NAME (one with NAME.confidence beside it) and prints the
// confidence the page plotted along the incidence slice as JSON: {"points": [[theta_o, confidence], ...]}; then
// unticks "Show the confidence" and reports whether the plot is hidden.
// Usage: node confidence.mjs URL NAME
import { launch } from "./launch.mjs";

const [url, name] = process.argv.slice(2);
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(`${url}#grids=${encodeURIComponent(name)}`);
  await page.waitForSelector("#confidence g.confidence circle", { timeout: 20000 });
  const points = await page.$$eval("#confidence g.confidence circle", (cs) =>
    cs.map((c) => [Number(c.getAttribute("data-nm")), Number(c.getAttribute("data-value"))]));
  await page.uncheck("#show-confidence");
  const hidden = await page.$eval("#confidence", (e) => getComputedStyle(e).display === "none");
  if (errors.length) throw new Error(`the page threw: ${errors.join("; ")}`);
  console.log(JSON.stringify({ hidden, points }));
} finally {
  await browser.close();
}
