// Debian's Chromium, headless, with the flags this machine needs (no sandbox as root; no background networking,
// whose connections the closed network refuses). CHROMIUM overrides the executable.
import { chromium } from "playwright-core";

export function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-quic",
           "--no-first-run", "--disable-component-update", "--disable-sync"],
  });
}
