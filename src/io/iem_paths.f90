!> File paths as the operating system sees them: what a path is (file, folder, device...),
!> whether a folder is writable, the resolved absolute form, and the length limits, for the
!> checks made before a run writes anything (docs/output.md, "Files").
module iem_paths
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
  implicit none
  private
  public :: path_kind, folder_writable, file_readable, resolved_path, folder_of, name_of
  public :: why_not_readable, mpiio_name
  public :: path_none, path_file, path_folder, path_special, path_unknown
  public :: name_max, path_max, mpiio_path_max

  !> What path_kind finds: nothing, a regular file, a folder, a special file (device, pipe,
  !> socket), or something that cannot be looked at (a dangling link, no permission).
  integer, parameter :: path_none = 0, path_file = 1, path_folder = 2, path_special = 3, &
                        path_unknown = -1
  !> Longest file name (one component) and whole path that iem writes: Linux's NAME_MAX and
  !> PATH_MAX less the terminating NUL, which MPI-IO and HDF5 also assume.
  integer, parameter :: name_max = 255, path_max = 4095
  !> Longest path, as written, of a file opened through MPI-IO (the output through HDF5's
  !> MPI-IO driver, checkpoints): Open MPI 4.1's MPI-IO builds names of its own from it in
  !> fixed 256-byte buffers and aborts on a longer one (measured: 245 characters abort).
  integer, parameter :: mpiio_path_max = 200

  interface
    function c_path_kind(path) bind(C, name='iem_path_kind') result(k)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: k
    end function c_path_kind
    function c_folder_writable(path) bind(C, name='iem_folder_writable') result(ok)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: ok
    end function c_folder_writable
    function c_file_readable(path) bind(C, name='iem_file_readable') result(ok)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: ok
    end function c_file_readable
    function c_resolve(path, out, n) bind(C, name='iem_resolve') result(len)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: path(*)
      character(kind=c_char), intent(out) :: out(*)
      integer(c_int), value :: n
      integer(c_int) :: len
    end function c_resolve
  end interface

contains

  !> What path is, following links: path_none, path_file, path_folder, path_special or
  !> path_unknown.
  integer function path_kind(path) result(k)
    character(len=*), intent(in) :: path
    k = int(c_path_kind(path//c_null_char))
  end function path_kind

  !> True when files can be created in the folder path.
  logical function folder_writable(path) result(ok)
    character(len=*), intent(in) :: path
    ok = c_folder_writable(path//c_null_char) == 1_c_int
  end function folder_writable

  !> True when path can be opened for reading.
  logical function file_readable(path) result(ok)
    character(len=*), intent(in) :: path
    ok = c_file_readable(path//c_null_char) == 1_c_int
  end function file_readable

  !> Why path cannot be read as a file ('' when it can).
  function why_not_readable(path) result(why)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: why
    why = ''
    select case (path_kind(path))
    case (path_none)
      why = 'no such file'
    case (path_folder)
      why = 'it is a folder'
    case (path_special)
      why = 'it is not a regular file (a device, pipe or socket)'
    case (path_file)
      if (.not. file_readable(path)) why = 'it is not readable'
    case default
      why = 'it cannot be looked at (a dangling link, or no permission)'
    end select
  end function why_not_readable

  !> The name to give MPI-IO (and HDF5's MPI-IO driver) for path: './' is put before a name
  !> without a folder, since Open MPI 4.1 fails to open a one-character one ('a').
  pure function mpiio_name(path) result(name)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: name
    if (index(path, '/') == 0) then
      name = './'//path
    else
      name = path
    end if
  end function mpiio_name

  !> The folder part of path ('.' when it has none).
  pure function folder_of(path) result(folder)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: folder
    integer :: k
    k = index(path, '/', back=.true.)
    if (k == 0) then
      folder = '.'
    else if (k == 1) then
      folder = '/'
    else
      folder = path(1:k - 1)
    end if
  end function folder_of

  !> The file-name part of path (after its last '/').
  pure function name_of(path) result(name)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: name
    name = path(index(path, '/', back=.true.) + 1:)
  end function name_of

  !> The absolute path with links, '.' and '..' resolved: of the file itself when it exists
  !> (so a link and its target compare equal), else of its folder joined with its name;
  !> '' when the folder cannot be resolved.
  function resolved_path(path) result(out)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: out
    out = resolve(path)
    if (len(out) > 0) return
    out = resolve(folder_of(path))
    if (len(out) == 0) return
    if (out == '/') then
      out = '/'//name_of(path)
    else
      out = out//'/'//name_of(path)
    end if
  end function resolved_path

  function resolve(path) result(out)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: out
    character(kind=c_char, len=path_max + 1) :: buf
    integer(c_int) :: n
    n = c_resolve(path//c_null_char, buf, int(len(buf), c_int))
    if (n < 0) then
      out = ''
    else
      out = buf(1:n)
    end if
  end function resolve
end module iem_paths
