#include "server/storage/testing/fault_vfs.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace shapeid {

// One registered VFS over one of SQLite's (unix or unix-none).
struct WrappedVfs {
  sqlite3_vfs vfs{};
  sqlite3_vfs* base = nullptr;
  std::string name;
  FaultVfs::State* state = nullptr;
};

struct FaultVfs::State {
  std::string name;
  mutable std::mutex mu;
  Faults faults;  // guarded by mu
  std::atomic<int> injected{0};
  WrappedVfs unix_vfs;
  WrappedVfs none_vfs;

  // The faults for `path`, or none.
  Faults For(const char* path) const {
    std::lock_guard<std::mutex> lock(mu);
    if (!faults.path_contains.empty() &&
        (path == nullptr || std::strstr(path, faults.path_contains.c_str()) == nullptr)) {
      return Faults{};
    }
    return faults;
  }
  // Counts one injected failure and leaves its errno where unix's xGetLastError reads it.
  int Inject(int code, int error) {
    injected.fetch_add(1);
    errno = error;
    return code;
  }
};

namespace {

// A file opened through the wrapper: ours first, then the wrapped VFS's file.
struct FaultFile {
  sqlite3_file base;
  FaultVfs::State* state;
  const char* path;  // valid until xClose (SQLite's guarantee for xOpen's name); "" for temps
  int flags;
  sqlite3_file* real;
};

constexpr size_t kHeaderSize = (sizeof(FaultFile) + 15) & ~size_t{15};

FaultFile* Of(sqlite3_file* file) { return reinterpret_cast<FaultFile*>(file); }
sqlite3_file* Real(sqlite3_file* file) { return Of(file)->real; }

bool Exists(const std::string& path) { return access(path.c_str(), F_OK) == 0; }

int64_t SizeOf(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 ? static_cast<int64_t>(st.st_size) : 0;
}

int Close(sqlite3_file* f) { return Real(f)->pMethods->xClose(Real(f)); }

int Read(sqlite3_file* f, void* buf, int amount, sqlite3_int64 offset) {
  FaultFile* ff = Of(f);
  if ((ff->flags & SQLITE_OPEN_MAIN_DB) != 0) {
    const FaultVfs::Faults faults = ff->state->For(ff->path);
    if (faults.read_error != SQLITE_OK) return ff->state->Inject(faults.read_error, faults.error);
  }
  return Real(f)->pMethods->xRead(Real(f), buf, amount, offset);
}

int Write(sqlite3_file* f, const void* buf, int amount, sqlite3_int64 offset) {
  FaultFile* ff = Of(f);
  if (ff->state->For(ff->path).fail_growth) {
    sqlite3_int64 size = 0;
    if (Real(f)->pMethods->xFileSize(Real(f), &size) == SQLITE_OK && offset + amount > size) {
      return ff->state->Inject(SQLITE_FULL, ENOSPC);
    }
  }
  return Real(f)->pMethods->xWrite(Real(f), buf, amount, offset);
}

int Truncate(sqlite3_file* f, sqlite3_int64 size) {
  FaultFile* ff = Of(f);
  if (ff->state->For(ff->path).fail_growth) {
    sqlite3_int64 current = 0;
    if (Real(f)->pMethods->xFileSize(Real(f), &current) == SQLITE_OK && size > current) {
      return ff->state->Inject(SQLITE_FULL, ENOSPC);
    }
  }
  return Real(f)->pMethods->xTruncate(Real(f), size);
}

int Sync(sqlite3_file* f, int flags) { return Real(f)->pMethods->xSync(Real(f), flags); }
int FileSize(sqlite3_file* f, sqlite3_int64* size) {
  return Real(f)->pMethods->xFileSize(Real(f), size);
}
int Lock(sqlite3_file* f, int level) { return Real(f)->pMethods->xLock(Real(f), level); }
int Unlock(sqlite3_file* f, int level) { return Real(f)->pMethods->xUnlock(Real(f), level); }
int CheckReservedLock(sqlite3_file* f, int* out) {
  return Real(f)->pMethods->xCheckReservedLock(Real(f), out);
}
int FileControl(sqlite3_file* f, int op, void* arg) {
  return Real(f)->pMethods->xFileControl(Real(f), op, arg);
}
int SectorSize(sqlite3_file* f) { return Real(f)->pMethods->xSectorSize(Real(f)); }
int DeviceCharacteristics(sqlite3_file* f) {
  return Real(f)->pMethods->xDeviceCharacteristics(Real(f));
}

// Called on the main database file; SQLite's unix VFS opens (creates) the -shm at the first
// call and writes a byte into each new page to allocate it, failing IOERR_SHMSIZE when the
// disk is full.
int ShmMap(sqlite3_file* f, int region, int region_size, int extend, void volatile** out) {
  FaultFile* ff = Of(f);
  const FaultVfs::Faults faults = ff->state->For(ff->path);
  const std::string shm = std::string(ff->path) + "-shm";
  if (faults.shm_error != SQLITE_OK) return ff->state->Inject(faults.shm_error, faults.error);
  if (faults.fail_create && !Exists(shm)) return ff->state->Inject(SQLITE_CANTOPEN, faults.error);
  if (faults.read_only) return ff->state->Inject(SQLITE_READONLY_CANTINIT, faults.error);
  if (faults.fail_growth && extend != 0 &&
      static_cast<int64_t>(region + 1) * region_size > SizeOf(shm)) {
    return ff->state->Inject(SQLITE_IOERR_SHMSIZE, ENOSPC);
  }
  return Real(f)->pMethods->xShmMap(Real(f), region, region_size, extend, out);
}
int ShmLock(sqlite3_file* f, int offset, int n, int flags) {
  return Real(f)->pMethods->xShmLock(Real(f), offset, n, flags);
}
void ShmBarrier(sqlite3_file* f) { Real(f)->pMethods->xShmBarrier(Real(f)); }
int ShmUnmap(sqlite3_file* f, int delete_flag) {
  return Real(f)->pMethods->xShmUnmap(Real(f), delete_flag);
}

// Memory-mapped reads would bypass Read: refused while reads fail.
int Fetch(sqlite3_file* f, sqlite3_int64 offset, int amount, void** out) {
  FaultFile* ff = Of(f);
  if (ff->state->For(ff->path).read_error != SQLITE_OK) {
    *out = nullptr;
    return SQLITE_OK;
  }
  return Real(f)->pMethods->xFetch(Real(f), offset, amount, out);
}
int Unfetch(sqlite3_file* f, sqlite3_int64 offset, void* page) {
  return Real(f)->pMethods->xUnfetch(Real(f), offset, page);
}

// Two tables: a file whose wrapped methods have no shared memory (unix-none) must not seem
// to have some, or SQLite would use it.
sqlite3_io_methods Methods(bool shared_memory) {
  sqlite3_io_methods m{};
  m.iVersion = 3;
  m.xClose = Close;
  m.xRead = Read;
  m.xWrite = Write;
  m.xTruncate = Truncate;
  m.xSync = Sync;
  m.xFileSize = FileSize;
  m.xLock = Lock;
  m.xUnlock = Unlock;
  m.xCheckReservedLock = CheckReservedLock;
  m.xFileControl = FileControl;
  m.xSectorSize = SectorSize;
  m.xDeviceCharacteristics = DeviceCharacteristics;
  if (shared_memory) {
    m.xShmMap = ShmMap;
    m.xShmLock = ShmLock;
    m.xShmBarrier = ShmBarrier;
    m.xShmUnmap = ShmUnmap;
  }
  m.xFetch = Fetch;
  m.xUnfetch = Unfetch;
  return m;
}
const sqlite3_io_methods kWithShm = Methods(true);
const sqlite3_io_methods kWithoutShm = Methods(false);

WrappedVfs* Wrapped(sqlite3_vfs* vfs) { return static_cast<WrappedVfs*>(vfs->pAppData); }
sqlite3_vfs* Base(sqlite3_vfs* vfs) { return Wrapped(vfs)->base; }

int Open(sqlite3_vfs* vfs, const char* name, sqlite3_file* file, int flags, int* out_flags) {
  WrappedVfs* w = Wrapped(vfs);
  FaultFile* ff = Of(file);
  ff->base.pMethods = nullptr;  // until the wrapped open succeeds: SQLite then skips xClose
  ff->state = w->state;
  ff->path = name != nullptr ? name : "";
  ff->flags = flags;
  ff->real = reinterpret_cast<sqlite3_file*>(reinterpret_cast<char*>(file) + kHeaderSize);
  std::memset(ff->real, 0, static_cast<size_t>(w->base->szOsFile));
  const FaultVfs::Faults faults = w->state->For(name);
  const bool exists = name != nullptr && Exists(name);
  if (name != nullptr && !exists && (flags & SQLITE_OPEN_CREATE) != 0 && faults.fail_create) {
    return w->state->Inject(SQLITE_CANTOPEN, faults.error);
  }
  if (exists && faults.read_only && (flags & SQLITE_OPEN_READWRITE) != 0) {
    // What unix does itself when O_RDWR fails with EROFS.
    w->state->Inject(SQLITE_OK, faults.error);
    flags = (flags & ~(SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE)) | SQLITE_OPEN_READONLY;
  }
  const int rc = w->base->xOpen(w->base, name, ff->real, flags, out_flags);
  if (ff->real->pMethods != nullptr) {
    ff->base.pMethods = ff->real->pMethods->xShmMap != nullptr ? &kWithShm : &kWithoutShm;
  }
  return rc;
}

int Delete(sqlite3_vfs* vfs, const char* name, int sync_dir) {
  WrappedVfs* w = Wrapped(vfs);
  const FaultVfs::Faults faults = w->state->For(name);
  if (faults.read_only) return w->state->Inject(SQLITE_IOERR_DELETE, faults.error);
  return w->base->xDelete(w->base, name, sync_dir);
}

int Access(sqlite3_vfs* vfs, const char* name, int flags, int* out) {
  return Base(vfs)->xAccess(Base(vfs), name, flags, out);
}
int FullPathname(sqlite3_vfs* vfs, const char* name, int size, char* out) {
  return Base(vfs)->xFullPathname(Base(vfs), name, size, out);
}
void* DlOpen(sqlite3_vfs* vfs, const char* name) { return Base(vfs)->xDlOpen(Base(vfs), name); }
void DlError(sqlite3_vfs* vfs, int size, char* out) { Base(vfs)->xDlError(Base(vfs), size, out); }
void (*DlSym(sqlite3_vfs* vfs, void* handle, const char* symbol))(void) {
  return Base(vfs)->xDlSym(Base(vfs), handle, symbol);
}
void DlClose(sqlite3_vfs* vfs, void* handle) { Base(vfs)->xDlClose(Base(vfs), handle); }
int Randomness(sqlite3_vfs* vfs, int size, char* out) {
  return Base(vfs)->xRandomness(Base(vfs), size, out);
}
int Sleep(sqlite3_vfs* vfs, int micros) { return Base(vfs)->xSleep(Base(vfs), micros); }
int CurrentTime(sqlite3_vfs* vfs, double* out) { return Base(vfs)->xCurrentTime(Base(vfs), out); }
int GetLastError(sqlite3_vfs* vfs, int size, char* out) {
  return Base(vfs)->xGetLastError(Base(vfs), size, out);
}
int CurrentTimeInt64(sqlite3_vfs* vfs, sqlite3_int64* out) {
  return Base(vfs)->xCurrentTimeInt64(Base(vfs), out);
}

// Registers `w` as `name` over SQLite's `base`; false if there is no such VFS.
bool Register(WrappedVfs* w, FaultVfs::State* state, std::string name, const char* base) {
  w->base = sqlite3_vfs_find(base);
  if (w->base == nullptr) return false;
  w->name = std::move(name);
  w->state = state;
  sqlite3_vfs& v = w->vfs;
  v.iVersion = 2;  // no system-call overrides: those would reach unix's, not ours
  v.szOsFile = static_cast<int>(kHeaderSize) + w->base->szOsFile;
  v.mxPathname = w->base->mxPathname;
  v.zName = w->name.c_str();
  v.pAppData = w;
  v.xOpen = Open;
  v.xDelete = Delete;
  v.xAccess = Access;
  v.xFullPathname = FullPathname;
  v.xDlOpen = DlOpen;
  v.xDlError = DlError;
  v.xDlSym = DlSym;
  v.xDlClose = DlClose;
  v.xRandomness = Randomness;
  v.xSleep = Sleep;
  v.xCurrentTime = CurrentTime;
  v.xGetLastError = GetLastError;
  v.xCurrentTimeInt64 = CurrentTimeInt64;
  return sqlite3_vfs_register(&w->vfs, /*makeDflt=*/0) == SQLITE_OK;
}

}  // namespace

FaultVfs::Faults FaultVfs::DiskFull() {
  Faults f;
  f.fail_create = true;
  f.fail_growth = true;
  f.error = ENOSPC;
  return f;
}

FaultVfs::Faults FaultVfs::ReadOnlyVolume() {
  Faults f;
  f.read_only = true;
  f.fail_create = true;
  f.error = EROFS;
  return f;
}

FaultVfs::FaultVfs(std::string name) : state_(std::make_unique<State>()) {
  state_->name = std::move(name);
  if (!Register(&state_->unix_vfs, state_.get(), state_->name, "unix") ||
      !Register(&state_->none_vfs, state_.get(), state_->name + "-none", "unix-none")) {
    std::abort();  // SQLite without its unix VFSes: no test here could mean anything
  }
}

FaultVfs::~FaultVfs() {
  sqlite3_vfs_unregister(&state_->none_vfs.vfs);
  sqlite3_vfs_unregister(&state_->unix_vfs.vfs);
}

const std::string& FaultVfs::name() const { return state_->name; }

void FaultVfs::Set(Faults faults) {
  std::lock_guard<std::mutex> lock(state_->mu);
  state_->faults = std::move(faults);
}

int FaultVfs::injected() const { return state_->injected.load(); }

}  // namespace shapeid
