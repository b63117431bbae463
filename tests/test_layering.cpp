// Checks the layering rule of DESIGN.md: pm/ and blocks/ never include a GL or window header.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

namespace fs = std::filesystem;

TEST(Layering, CoreNeverIncludesGraphicsHeaders) {
  const std::regex gl(R"(#\s*include\s*[<"](GL/|GLES|EGL/|GLFW/|glad/|epoxy/|OSMesa|GL\.h))");
  int files = 0;
  for (const char* folder : {"pm", "blocks"}) {
    const fs::path root = fs::path(TERRALOD_SOURCE_DIR) / folder;
    ASSERT_TRUE(fs::is_directory(root)) << root;
    for (const auto& entry : fs::recursive_directory_iterator(root)) {
      if (!entry.is_regular_file()) continue;
      const std::string ext = entry.path().extension().string();
      if (ext != ".cpp" && ext != ".hpp" && ext != ".h") continue;
      ++files;
      std::ifstream in(entry.path());
      std::string line;
      for (int n = 1; std::getline(in, line); ++n)
        EXPECT_FALSE(std::regex_search(line, gl)) << entry.path().string() << ":" << n << ": " << line;
    }
  }
  EXPECT_GT(files, 5) << "the scan found too few sources; is TERRALOD_SOURCE_DIR right?";
}
