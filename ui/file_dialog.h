#pragma once
// A small file browser for the editor's Open scene, Save scene as, Export and Play edit log:
// a folder listing filtered by extension, navigation up and into folders, a name field,
// confirm and cancel. The listing and the choice of a path are display-free (FileBrowser,
// unit-tested in tests/ui/file_dialog_test.cpp against a temporary folder tree); drawFileDialog
// draws one as a Dear ImGui modal popup.
//
// Index: listing a folder · FileBrowser · drawing

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Listing a folder.

/// One row of a folder listing.
struct FileEntry {
    std::string name;  ///< file name within the folder
    bool directory = false;
    std::uintmax_t size = 0;  ///< bytes; 0 for folders
    std::string toString() const;
};

/// Whether `name`'s extension is one of `extensions` (each with its dot, compared without case;
/// ".gltf" matches "a.GLTF"). An empty list matches every name.
bool matchesExtension(const std::string& name, const std::vector<std::string>& extensions);

/// The entries of `folder`: sub-folders first, then files matching `extensions`, each group
/// sorted by name without case. Names starting with '.' are left out unless `showHidden`.
/// Entries that cannot be inspected are skipped. Throws std::filesystem::filesystem_error
/// when the folder cannot be read.
std::vector<FileEntry> listFolder(const std::string& folder,
                                  const std::vector<std::string>& extensions,
                                  bool showHidden = false);

// ---------------------------------------------------------------------------------------------
// FileBrowser.

enum class FileDialogKind {
    Open,  ///< the chosen file must exist
    Save,  ///< the chosen file's folder must exist; the file may
};

/// The state of one file dialog: the folder shown, its listing and the name field.
class FileBrowser {
public:
    /// Starts in the folder of `initialPath` (a file or folder; the current folder when it is
    /// "" or missing) with the name field set to its file name when it names a file.
    /// `extensions` filters the listing (".json"); `defaultExtension` is appended on Save when
    /// the name has none of `extensions` (e.g. ".json"; "" for none).
    FileBrowser(FileDialogKind kind, const std::string& initialPath,
                std::vector<std::string> extensions, std::string defaultExtension = "");

    /// The folder shown (absolute, normalised).
    const std::string& folder() const { return mFolder; }
    const std::vector<FileEntry>& entries() const { return mEntries; }
    /// Why the folder could not be listed ("" when it could).
    const std::string& error() const { return mError; }
    const std::vector<std::string>& extensions() const { return mExtensions; }
    FileDialogKind kind() const { return mKind; }

    /// The name field (a name in the folder, or a path relative to it, or absolute).
    std::string name;
    bool showHidden = false;
    /// The dialog's message line (why the last confirm failed).
    std::string message;

    /// Shows `folder` (relative to the current one, or absolute); false and nothing changes when
    /// it is not a readable folder.
    bool navigate(const std::string& folder);
    /// Shows the parent folder; false at the root.
    bool up();
    /// Re-reads the folder (after showHidden changed, or files appeared).
    void refresh();
    /// Clicking an entry: a folder is entered (name kept), a file's name goes to the name field.
    /// Returns true when a folder was entered.
    bool activate(const FileEntry& entry);

    /// The path the dialog would return now, or nullopt with `why` set: an empty name; a name
    /// that is a folder (confirming it enters it instead: see confirm); Open: a missing file;
    /// Save: a missing parent folder. Save appends the default extension when the name has
    /// none of the dialog's extensions.
    std::optional<std::string> resolve(std::string* why = nullptr) const;
    /// Confirm (OK or Enter): a name naming a folder navigates into it and clears the name
    /// (returns nullopt); otherwise resolve().
    std::optional<std::string> confirm(std::string* why = nullptr);

    std::string toString() const;

private:
    FileDialogKind mKind;
    std::vector<std::string> mExtensions;
    std::string mDefaultExtension;
    std::string mFolder;
    std::vector<FileEntry> mEntries;
    std::string mError;
};

// ---------------------------------------------------------------------------------------------
// Drawing.

/// What the popup did this frame.
enum class FileDialogResult { Open, Confirmed, Cancelled };

/// Draws `browser` as the modal popup `title` (the caller calls ImGui::OpenPopup(title) once):
/// the folder with an "up" button, the listing (folders marked '/'; double click enters a
/// folder or confirms a file), the name field (Enter confirms), a message line, OK and Cancel.
/// Returns Confirmed with `*chosen` set once OK (or Enter, or a double click) gives a valid
/// path; the popup is then closed. Must be called between ImGui::NewFrame and Render.
FileDialogResult drawFileDialog(const char* title, FileBrowser& browser, std::string* chosen);

}  // namespace penumbra
