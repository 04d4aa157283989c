// write_replacing (forward/io/replace_file.hpp): a file is replaced whole or not at all, and
// a write that fails (a full disk, here a file-size limit) is an InputError naming the file.

#include "forward/common/error.hpp"
#include "forward/io/replace_file.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <stdexcept>

using namespace diffipc;
namespace fs = std::filesystem;

namespace {

std::string read(const fs::path& path) { return test::read_file(path.string()); }

/// Limits the size of files this process writes (RLIMIT_FSIZE) for its lifetime: writes
/// beyond it fail with EFBIG, as on a full disk (SIGXFSZ ignored meanwhile).
class FileSizeLimit {
public:
    explicit FileSizeLimit(rlim_t bytes)
    {
        getrlimit(RLIMIT_FSIZE, &m_old);
        m_handler = std::signal(SIGXFSZ, SIG_IGN);
        rlimit limit = m_old;
        limit.rlim_cur = bytes;
        setrlimit(RLIMIT_FSIZE, &limit);
    }
    ~FileSizeLimit()
    {
        setrlimit(RLIMIT_FSIZE, &m_old);
        std::signal(SIGXFSZ, m_handler);
    }

private:
    rlimit m_old {};
    void (*m_handler)(int) = nullptr;
};

fs::path scratch(const std::string& name)
{
    const fs::path dir = fs::temp_directory_path() / "diffipc_replace_file";
    fs::create_directories(dir);
    return dir / name;
}

} // namespace

TEST(ReplaceFile, ReplacesTheFileWhole)
{
    const fs::path path = scratch("whole.txt");
    std::ofstream(path) << "old";
    write_replacing(path.string(), [](std::ostream& out) { out << "new\n" << std::string(1, '\0') << "binary"; });
    EXPECT_EQ(read(path), std::string("new\n") + '\0' + "binary");
    EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
}

TEST(ReplaceFile, AFailedWriteNamesTheFileAndKeepsTheOldOne)
{
    const fs::path path = scratch("full.vtu");
    std::ofstream(path) << "old";
    try {
        const FileSizeLimit limit(64 * 1024);
        write_replacing(path.string(), [](std::ostream& out) {
            const std::string block(4096, 'x');
            for (int i = 0; i < 256; ++i) // 1 MB
                out << block;
        });
        FAIL() << "a write past the file-size limit was not reported";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), path.string());
        EXPECT_NE(std::string(e.what()).find("cannot write file"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("too large"), std::string::npos) << e.what(); // EFBIG's reason
    }
    EXPECT_EQ(read(path), "old");
    EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
}

TEST(ReplaceFile, AnExceptionOfTheWriterLeavesNoTemporary)
{
    const fs::path path = scratch("thrown.txt");
    fs::remove(path);
    EXPECT_THROW(write_replacing(path.string(),
                     [](std::ostream& out) {
                         out << "half";
                         throw std::runtime_error("stop");
                     }),
        std::runtime_error);
    EXPECT_FALSE(fs::exists(path));
    EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
}

TEST(ReplaceFile, AMissingDirectoryNamesTheFile)
{
    const std::string path = "/nonexistent/diffipc/frame_0.vtu";
    try {
        write_replacing(path, [](std::ostream& out) { out << "x"; });
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), path);
    }
}

TEST(ReplaceFile, ALinkToAFullDeviceIsAFailedWriteNamingTheLink)
{
    // Before: the link was renamed over, the run went on (exit 0) and the link's target never
    // saw the data.
    if (!fs::exists("/dev/full"))
        GTEST_SKIP() << "no /dev/full";
    const fs::path path = scratch("full_link.json");
    fs::remove(path);
    fs::create_symlink("/dev/full", path);
    try {
        write_replacing(path.string(), [](std::ostream& out) { out << std::string(1 << 16, 'x'); });
        FAIL() << "a write to /dev/full was not reported";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), path.string());
        EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
    }
    EXPECT_TRUE(fs::is_symlink(path));
    EXPECT_FALSE(fs::exists("/dev/full.tmp"));
}

TEST(ReplaceFile, ALinkedFileIsReplacedAndTheLinkKept)
{
    const fs::path target = scratch("linked_target.txt"), link = scratch("link.txt");
    fs::remove(link);
    std::ofstream(target) << "old";
    fs::create_symlink(target, link);
    write_replacing(link.string(), [](std::ostream& out) { out << "new"; });
    EXPECT_TRUE(fs::is_symlink(link));
    EXPECT_EQ(read(target), "new");
    EXPECT_FALSE(fs::exists(target.string() + ".tmp"));
    EXPECT_FALSE(fs::exists(link.string() + ".tmp"));
}

TEST(ReplaceFile, ADirectoryIsRefusedNamingIt)
{
    const fs::path path = scratch("a_directory.vtu");
    fs::create_directories(path);
    try {
        write_replacing(path.string(), [](std::ostream& out) { out << "x"; });
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), path.string());
    }
    EXPECT_TRUE(fs::is_directory(path));
}

TEST(ReplaceFile, ADanglingLinkCreatesTheFileItNames)
{
    const fs::path dir = scratch("links");
    fs::create_directories(dir);
    const fs::path link = dir / "summary.json";
    fs::remove(link);
    fs::remove(dir / "run.json");
    fs::create_symlink("run.json", link); // relative to the link's folder
    write_replacing(link.string(), [](std::ostream& out) { out << "data"; });
    EXPECT_TRUE(fs::is_symlink(link));
    EXPECT_EQ(read(dir / "run.json"), "data");
}
