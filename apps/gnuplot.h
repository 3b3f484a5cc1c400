#pragma once
// Plots drawn by gnuplot as a child process (PNG), for subcommands that offer figures.
#include <filesystem>
#include <string>
#include <string_view>

namespace specula::app {

/// The gnuplot executable on PATH, or an empty path when there is none.
std::filesystem::path find_gnuplot();
/// s as a gnuplot string literal.
std::string gnuplot_quote(std::string_view s);
/// The "set terminal" line for a width x height PNG (pngcairo when available).
std::string gnuplot_png_terminal(int width, int height);
/// Draws `target` (a PNG) with a gnuplot script whose output line is added here, so it appears only when complete.
void plot_png(const std::filesystem::path& gnuplot, const std::filesystem::path& target, const std::string& terminal,
              const std::string& body);

}  // namespace specula::app
