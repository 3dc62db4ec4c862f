!> Low-level collective HDF5 operations of the output writer (iem_h5_output): scalar
!> attributes, extendible series (create, extend and select the new samples), selections of
!> runs of global indices, memory spaces, closing, and the error record of each HDF5 call.
!>
!> Failures are recorded in stat/msg (the first one kept, with `path`, the file, in the
!> message); every procedure but `failed` does nothing once stat /= 0.
module iem_h5_primitives
  use iem_kinds, only: wp, i8
  use iem_strings, only: itoa
  use hdf5, only: HID_T, HSIZE_T, SIZE_T, h5kind_to_type, H5_REAL_KIND, H5_INTEGER_KIND, &
    h5pcreate_f, h5pclose_f, h5pset_fill_time_f, h5pset_chunk_f, H5P_DATASET_CREATE_F, &
    H5D_FILL_TIME_NEVER_F, h5dcreate_f, h5dclose_f, h5dset_extent_f, h5dget_space_f, &
    h5screate_f, h5screate_simple_f, h5dopen_f, h5sget_simple_extent_dims_f, h5scopy_f, &
    h5sclose_f, h5sselect_hyperslab_f, &
    h5sselect_none_f, H5S_SCALAR_F, H5S_SELECT_SET_F, H5S_SELECT_OR_F, H5S_UNLIMITED_F, &
    h5acreate_f, h5awrite_f, h5aclose_f, h5tcopy_f, h5tset_size_f, h5tset_strpad_f, h5tclose_f, &
    H5T_FORTRAN_S1, H5T_STR_NULLPAD_F, H5T_NATIVE_INTEGER, H5T_STD_I32LE, H5T_STD_I64LE, &
    H5T_IEEE_F64LE
  use, intrinsic :: iso_c_binding, only: c_int, c_int64_t
  implicit none
  private
  public :: failed, put_attr, create_series, prepare_append, select_runs, &
    make_mem_space, close_space, close_dset, gid_runs, open_cut

  interface
    !> C H5Smodify_select (HDF5 >= 1.10.7; no Fortran wrapper in 1.10): merges the selection
    !> of space2 into that of space1 with operator op. Negative on failure. hid_t is int64_t.
    function h5s_modify_select(space1, op, space2) bind(C, name='H5Smodify_select') &
        result(herr)
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: space1, space2
      integer(c_int), value :: op
      integer(c_int) :: herr
    end function h5s_modify_select
  end interface

  !> Samples per chunk of the extendible datasets (history, /frames/time, /frames/step).
  integer(HSIZE_T), parameter :: series_chunk = 1024
  !> Dimensions of one element, for scalar attributes and single samples.
  integer(HSIZE_T), parameter, public :: one(1) = [1_HSIZE_T]

contains

  !> True if ierr reports an HDF5 failure; records the first failure in stat and msg.
  logical function failed(path, ierr, call_name, object, stat, msg)
    character(len=*), intent(in) :: path
    integer, intent(in) :: ierr
    character(len=*), intent(in) :: call_name, object
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg

    failed = ierr /= 0
    if (failed .and. stat == 0) then
      stat = 1
      msg = 'iem_h5_output: '//call_name//' failed on '//object//' in '//path
    end if
  end function failed

  !> Creates and writes the scalar attribute `name` of object `loc` (called `where` in
  !> messages) from whichever of text, ival, lval, rval is present. No-op if stat /= 0.
  subroutine put_attr(path, loc, where, name, stat, msg, text, ival, lval, rval)
    character(len=*), intent(in) :: path
    integer(HID_T), intent(in) :: loc
    character(len=*), intent(in) :: where, name
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    character(len=*), intent(in), optional :: text
    integer, intent(in), optional :: ival
    integer(i8), intent(in), optional :: lval
    real(wp), intent(in), optional :: rval
    character(len=:), allocatable :: obj
    integer(HID_T) :: space, ftype, mtype, attr
    integer :: ierr
    logical :: own_type

    if (stat /= 0) return
    obj = where//' attribute '//name
    space = -1
    attr = -1
    own_type = .false.
    work: block
      call h5screate_f(H5S_SCALAR_F, space, ierr)
      if (failed(path, ierr, 'h5screate_f', obj, stat, msg)) exit work
      if (present(text)) then
        ! Fixed-length, null-padded; the same type in memory and file, so bytes go verbatim.
        call h5tcopy_f(H5T_FORTRAN_S1, ftype, ierr)
        if (failed(path, ierr, 'h5tcopy_f', obj, stat, msg)) exit work
        own_type = .true.
        call h5tset_size_f(ftype, int(max(len(text), 1), SIZE_T), ierr)
        if (failed(path, ierr, 'h5tset_size_f', obj, stat, msg)) exit work
        call h5tset_strpad_f(ftype, H5T_STR_NULLPAD_F, ierr)
        if (failed(path, ierr, 'h5tset_strpad_f', obj, stat, msg)) exit work
        mtype = ftype
      else if (present(ival)) then
        ftype = H5T_STD_I32LE
        mtype = H5T_NATIVE_INTEGER
      else if (present(lval)) then
        ftype = H5T_STD_I64LE
        mtype = h5kind_to_type(i8, H5_INTEGER_KIND)
      else
        ftype = H5T_IEEE_F64LE
        mtype = h5kind_to_type(wp, H5_REAL_KIND)
      end if
      call h5acreate_f(loc, name, ftype, space, attr, ierr)
      if (failed(path, ierr, 'h5acreate_f', obj, stat, msg)) exit work
      if (present(text)) then
        if (len(text) == 0) then
          call h5awrite_f(attr, mtype, achar(0), one, ierr)
        else
          call h5awrite_f(attr, mtype, text, one, ierr)
        end if
      else if (present(ival)) then
        call h5awrite_f(attr, mtype, ival, one, ierr)
      else if (present(lval)) then
        call h5awrite_f(attr, mtype, lval, one, ierr)
      else if (present(rval)) then
        call h5awrite_f(attr, mtype, rval, one, ierr)
      else
        ierr = -1
      end if
      if (failed(path, ierr, 'h5awrite_f', obj, stat, msg)) exit work
    end block work
    if (attr >= 0) then
      call h5aclose_f(attr, ierr)
      if (failed(path, ierr, 'h5aclose_f', obj, stat, msg)) continue
    end if
    if (own_type) then
      call h5tclose_f(ftype, ierr)
      if (failed(path, ierr, 'h5tclose_f', obj, stat, msg)) continue
    end if
    call close_space(path, space, stat, msg)
  end subroutine put_attr

  !> Creates the empty, extendible, chunked dataset `name` in `loc`: 1-D if ncomp == 0, else
  !> (ncomp, unlimited) in Fortran order. No-op if stat /= 0.
  subroutine create_series(path, loc, where, name, ftype, ncomp, dset, stat, msg)
    character(len=*), intent(in) :: path
    integer(HID_T), intent(in) :: loc, ftype
    character(len=*), intent(in) :: where, name
    integer, intent(in) :: ncomp
    integer(HID_T), intent(inout) :: dset
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(HSIZE_T) :: dims(2), maxdims(2), chunk(2)
    integer(HID_T) :: space, dcpl
    integer :: rank, ierr

    if (stat /= 0) return
    if (ncomp == 0) then
      rank = 1
      dims(1) = 0
      maxdims(1) = H5S_UNLIMITED_F
      chunk(1) = series_chunk
    else
      rank = 2
      dims = [int(ncomp, HSIZE_T), 0_HSIZE_T]
      maxdims = [int(ncomp, HSIZE_T), H5S_UNLIMITED_F]
      chunk = [int(ncomp, HSIZE_T), series_chunk]
    end if
    space = -1
    dcpl = -1
    work: block
      call h5screate_simple_f(rank, dims(:rank), space, ierr, maxdims(:rank))
      if (failed(path, ierr, 'h5screate_simple_f', where//name, stat, msg)) exit work
      call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, ierr)
      if (failed(path, ierr, 'h5pcreate_f', where//name, stat, msg)) exit work
      call h5pset_chunk_f(dcpl, rank, chunk(:rank), ierr)
      if (failed(path, ierr, 'h5pset_chunk_f', where//name, stat, msg)) exit work
      call h5pset_fill_time_f(dcpl, H5D_FILL_TIME_NEVER_F, ierr)
      if (failed(path, ierr, 'h5pset_fill_time_f', where//name, stat, msg)) exit work
      call h5dcreate_f(loc, name, ftype, space, dset, ierr, dcpl)
      if (failed(path, ierr, 'h5dcreate_f', where//name, stat, msg)) exit work
    end block work
    if (dcpl >= 0) then
      call h5pclose_f(dcpl, ierr)
      if (failed(path, ierr, 'h5pclose_f', where//name, stat, msg)) continue
    end if
    call close_space(path, space, stat, msg)
  end subroutine create_series

  !> Extends `dset` from `old` to `old + n` samples (ncomp components each, 0: 1-D) and
  !> returns a file space with the new samples selected if my_rank
  !> (the caller's rank in the file's communicator) is 0, none elsewhere, and a matching memory
  !> space of n samples.
  subroutine prepare_append(path, my_rank, dset, where, ncomp, old, n, fspace, mspace, stat, msg)
    character(len=*), intent(in) :: path
    integer, intent(in) :: my_rank
    integer(HID_T), intent(in) :: dset
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: old, n
    integer(HID_T), intent(inout) :: fspace, mspace
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(HSIZE_T) :: new_dims(2), start(2), count(2)
    integer :: rank, ierr

    if (stat /= 0) return
    if (ncomp == 0) then
      rank = 1
      new_dims(1) = int(old + n, HSIZE_T)
      start(1) = int(old, HSIZE_T)
      count(1) = int(n, HSIZE_T)
    else
      rank = 2
      new_dims = [int(ncomp, HSIZE_T), int(old + n, HSIZE_T)]
      start = [0_HSIZE_T, int(old, HSIZE_T)]
      count = [int(ncomp, HSIZE_T), int(n, HSIZE_T)]
    end if
    call h5dset_extent_f(dset, new_dims(:rank), ierr)
    if (failed(path, ierr, 'h5dset_extent_f', where, stat, msg)) return
    call h5dget_space_f(dset, fspace, ierr)
    if (failed(path, ierr, 'h5dget_space_f', where, stat, msg)) return
    call h5screate_simple_f(rank, count(:rank), mspace, ierr)
    if (failed(path, ierr, 'h5screate_simple_f', where, stat, msg)) return
    if (my_rank == 0) then
      call h5sselect_hyperslab_f(fspace, H5S_SELECT_SET_F, start(:rank), count(:rank), ierr)
      if (failed(path, ierr, 'h5sselect_hyperslab_f', where, stat, msg)) return
    else
      call h5sselect_none_f(fspace, ierr)
      if (failed(path, ierr, 'h5sselect_none_f', where, stat, msg)) return
      call h5sselect_none_f(mspace, ierr)
      if (failed(path, ierr, 'h5sselect_none_f', where, stat, msg)) return
    end if
  end subroutine prepare_append

  !> Selects in `space` the entries of the gid runs (starts 0-based, lengths): 1-D if
  !> ncomp == 0, else the whole first dimension of (ncomp, n). No-op if stat /= 0.
  subroutine select_runs(path, space, where, ncomp, starts, lens, stat, msg)
    character(len=*), intent(in) :: path
    integer(HID_T), intent(in) :: space
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: starts(:), lens(:)
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (stat /= 0) return
    if (size(starts) == 0) then
      call h5sselect_none_f(space, ierr)
      if (failed(path, ierr, 'h5sselect_none_f', where, stat, msg)) return
    else
      call select_run_range(path, space, where, ncomp, starts, lens, 1, size(starts), stat, msg)
    end if
  end subroutine select_runs

  !> Selects in `space` (whose selection is replaced) the runs lo..hi, as select_runs.
  !>
  !> Adding the runs one by one with H5S_SELECT_OR costs time proportional to the selection
  !> built so far in HDF5 1.10 (minutes for 50 000 runs); halving the range and merging the two
  !> halves with H5Smodify_select makes it O(n log n) (0.06 s for 50 000 runs).
  recursive subroutine select_run_range(path, space, where, ncomp, starts, lens, lo, hi, &
      stat, msg)
    character(len=*), intent(in) :: path
    integer(HID_T), intent(in) :: space
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp, lo, hi
    integer(i8), intent(in) :: starts(:), lens(:)
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer, parameter :: leaf_runs = 16
    integer(HSIZE_T) :: start(2), count(2)
    integer(HID_T) :: upper
    integer :: r, op, ierr, rank, mid

    if (stat /= 0) return
    if (hi - lo < leaf_runs) then
      rank = merge(1, 2, ncomp == 0)
      do r = lo, hi
        op = merge(H5S_SELECT_SET_F, H5S_SELECT_OR_F, r == lo)
        if (ncomp == 0) then
          start(1) = int(starts(r), HSIZE_T)
          count(1) = int(lens(r), HSIZE_T)
        else
          start = [0_HSIZE_T, int(starts(r), HSIZE_T)]
          count = [int(ncomp, HSIZE_T), int(lens(r), HSIZE_T)]
        end if
        call h5sselect_hyperslab_f(space, op, start(:rank), count(:rank), ierr)
        if (failed(path, ierr, 'h5sselect_hyperslab_f', where, stat, msg)) return
      end do
      return
    end if
    mid = lo + (hi - lo)/2
    ! Copied before `space` gets a selection, so that copies stay cheap.
    call h5scopy_f(space, upper, ierr)
    if (failed(path, ierr, 'h5scopy_f', where, stat, msg)) return
    call select_run_range(path, space, where, ncomp, starts, lens, lo, mid, stat, msg)
    call select_run_range(path, upper, where, ncomp, starts, lens, mid + 1, hi, stat, msg)
    if (stat == 0) then
      ierr = h5s_modify_select(int(space, c_int64_t), int(H5S_SELECT_OR_F, c_int), &
        int(upper, c_int64_t))
      if (failed(path, merge(-1, 0, ierr < 0), 'H5Smodify_select', where, stat, msg)) continue
    end if
    call close_space(path, upper, stat, msg)
  end subroutine select_run_range

  !> Memory space of n entries of ncomp components (0: 1-D); with nothing selected if n == 0.
  !> No-op if stat /= 0.
  subroutine make_mem_space(path, ncomp, n, where, space, stat, msg)
    character(len=*), intent(in) :: path
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: n
    character(len=*), intent(in) :: where
    integer(HID_T), intent(inout) :: space
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (stat /= 0) return
    if (n == 0) then
      call h5screate_f(H5S_SCALAR_F, space, ierr)
      if (failed(path, ierr, 'h5screate_f', where, stat, msg)) return
      call h5sselect_none_f(space, ierr)
      if (failed(path, ierr, 'h5sselect_none_f', where, stat, msg)) return
    else if (ncomp == 0) then
      call h5screate_simple_f(1, [int(n, HSIZE_T)], space, ierr)
      if (failed(path, ierr, 'h5screate_simple_f', where, stat, msg)) return
    else
      call h5screate_simple_f(2, [int(ncomp, HSIZE_T), int(n, HSIZE_T)], space, ierr)
      if (failed(path, ierr, 'h5screate_simple_f', where, stat, msg)) return
    end if
  end subroutine make_mem_space

  !> Closes dataspace `space` if open and marks it closed; records a failure in stat, msg.
  subroutine close_space(path, space, stat, msg)
    character(len=*), intent(in) :: path
    integer(HID_T), intent(inout) :: space
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (space < 0) return
    call h5sclose_f(space, ierr)
    space = -1
    if (failed(path, ierr, 'h5sclose_f', 'a dataspace', stat, msg)) continue
  end subroutine close_space

  !> Closes dataset `dset` if open and marks it closed; records a failure in stat, msg.
  subroutine close_dset(path, dset, where, stat, msg)
    character(len=*), intent(in) :: path
    integer(HID_T), intent(inout) :: dset
    character(len=*), intent(in) :: where
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (dset < 0) return
    call h5dclose_f(dset, ierr)
    dset = -1
    if (failed(path, ierr, 'h5dclose_f', where, stat, msg)) continue
  end subroutine close_dset

  !> Contiguous runs of strictly ascending ids: first id and length of each.
  pure subroutine gid_runs(gids, starts, lens)
    integer(i8), intent(in) :: gids(:)
    integer(i8), allocatable, intent(out) :: starts(:), lens(:)
    integer(i8) :: k, n, r

    n = size(gids, kind=i8)
    if (n == 0) then
      allocate (starts(0), lens(0))
      return
    end if
    allocate (starts(1 + count(gids(2:) /= gids(:n - 1) + 1)))
    allocate (lens(size(starts)))
    r = 1
    starts(1) = gids(1)
    lens(1) = 1
    do k = 2, n
      if (gids(k) == gids(k - 1) + 1) then
        lens(r) = lens(r) + 1
      else
        r = r + 1
        starts(r) = gids(k)
        lens(r) = 1
      end if
    end do
  end subroutine gid_runs


  !> Open the extendible series `name` under loc (called `where` in messages about the file
  !> path) unless open already (dset >= 0), and cut it to n entries (it must hold at least n;
  !> n < 0: keep them all); have: what it held. Collective; nothing once stat /= 0.
  subroutine open_cut(loc, path, name, where, ncomp, n, dset, stat, msg, have)
    integer(HID_T), intent(in) :: loc
    character(len=*), intent(in) :: path, name, where
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: n
    integer(HID_T), intent(inout) :: dset
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(i8), intent(out), optional :: have
    integer(HID_T) :: space
    integer(HSIZE_T) :: d(2), md(2)
    integer :: e, rank
    if (stat /= 0) return
    if (dset < 0) then
      call h5dopen_f(loc, name, dset, e)
      if (failed(path, e, 'h5dopen_f', where, stat, msg)) return
    end if
    call h5dget_space_f(dset, space, e)
    if (failed(path, e, 'h5dget_space_f', where, stat, msg)) return
    call h5sget_simple_extent_dims_f(space, d, md, rank)
    call h5sclose_f(space, e)
    rank = merge(1, 2, ncomp == 0)
    if (present(have)) have = int(d(rank), i8)
    if (n < 0) return
    if (d(rank) < int(n, HSIZE_T)) then
      stat = 1
      msg = 'iem_h5_output: '//path//': '//where//' holds '//itoa(int(d(rank), i8))// &
        ' entries, fewer than the '//itoa(n)//' the checkpoint needs'
      return
    end if
    if (ncomp == 0) then
      call h5dset_extent_f(dset, [int(n, HSIZE_T)], e)
    else
      call h5dset_extent_f(dset, [int(ncomp, HSIZE_T), int(n, HSIZE_T)], e)
    end if
    if (failed(path, e, 'h5dset_extent_f', where, stat, msg)) return
  end subroutine open_cut
end module iem_h5_primitives
