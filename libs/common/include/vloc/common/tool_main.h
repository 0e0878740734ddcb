#pragma once
// A command-line tool's main: an exception escaping the tool becomes one line
// on stderr and exit code 1 (an OpenCV error by its reason and function, not
// its multi-line text), never an abort.
//   int main(int argc, char** argv) {
//     vloc::InitLogging(argv[0]);
//     return vloc::RunTool("vloc_match", [&] { return Run(argc, argv); });
//   }

#include <opencv2/core.hpp>

#include <exception>
#include <iostream>

namespace vloc {

template <class Run>
int RunTool(const char* name, Run&& run) {
  try {
    return run();
  } catch (const cv::Exception& e) {
    std::cerr << name << ": OpenCV error: " << e.err << " (in " << e.func << "); stopped\n";
  } catch (const std::exception& e) {
    std::cerr << name << ": " << e.what() << "; stopped\n";
  }
  return 1;
}

}  // namespace vloc
