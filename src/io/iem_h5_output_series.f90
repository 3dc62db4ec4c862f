!> /history/reactions (every run) and /history/fracture (runs with fracture): their
!> creation, appending their samples and fracture events, and reopening them to continue an
!> interrupted run (cut back to what its checkpoint covers).
submodule (iem_h5_output) iem_h5_output_series
  use iem_strings, only: itoa
  use hdf5, only: HSIZE_T, h5fflush_f, H5F_SCOPE_GLOBAL_F, h5gcreate_f, h5gclose_f, h5dopen_f, &
    h5dread_f, h5dwrite_f, h5dget_space_f, h5dset_extent_f, h5sget_simple_extent_dims_f, &
    h5sclose_f, h5lexists_f, H5T_IEEE_F64LE, H5T_STD_I64LE, H5T_STD_I32LE, H5T_NATIVE_INTEGER
  use iem_h5_primitives, only: failed, put_attr, create_series, prepare_append, close_space, one, &
    open_cut
  implicit none

  !> The event series, in /history/fracture/events.
  character(len=*), parameter :: event_names(n_event_series) = [character(len=6) :: &
    'time', 'x', 'y', 'kind', 'cell', 'spring']
  character(len=*), parameter :: fr_where = '/history/fracture'

contains

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_define_reactions
    integer(HID_T) :: gid
    integer :: ierr, p
    character(len=:), allocatable :: where

    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: define_reactions on a file that is not open'
      return
    end if
    call reaction_paths(this, names)
    this%n_series_samples = 0
    gid = -1
    work: block
      call h5gcreate_f(this%file_id, '/history/reactions', gid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', '/history/reactions', stat, msg)) exit work
      do p = 1, size(names)
        where = trim(this%reaction_path(p))
        call create_series(this%path, gid, '/history/reactions/', trim(names(p)), &
          H5T_IEEE_F64LE, 2, this%reaction_id(p), stat, msg)
        call put_attr(this%path, this%reaction_id(p), where, 'bcs', stat, msg, text=trim(bcs(p)))
        if (stat /= 0) exit work
      end do
    end block work
    if (gid >= 0) call h5gclose_f(gid, ierr)
  end procedure h5_output_define_reactions

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_define_fracture_history
    integer(HID_T) :: gid, eid
    integer :: ierr, k
    integer(HID_T) :: ftype

    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: define_fracture_history on a file that is not open'
      return
    end if
    this%fracture = .true.
    this%n_events = 0
    gid = -1
    eid = -1
    work: block
      call h5gcreate_f(this%file_id, fr_where, gid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', fr_where, stat, msg)) exit work
      call h5gcreate_f(gid, 'events', eid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', fr_where//'/events', stat, msg)) exit work
      do k = 1, n_event_series
        select case (k)
        case (1:3)
          ftype = H5T_IEEE_F64LE
        case (5)
          ftype = H5T_STD_I64LE
        case default
          ftype = H5T_STD_I32LE
        end select
        call create_series(this%path, eid, fr_where//'/events/', trim(event_names(k)), ftype, &
          0, this%event_id(k), stat, msg)
      end do
      call put_attr(this%path, eid, fr_where//'/events', 'kinds', stat, msg, &
        text='1 tension, 2 crushing, 3 shear, 4 pre-cut')
      call put_attr(this%path, eid, fr_where//'/events', 'springs', stat, msg, &
        text='0-3 edges bottom, right, top, left; 4-7 shear springs at corners SW, SE, NE, NW')
      call create_series(this%path, gid, fr_where//'/', 'fragments', H5T_STD_I64LE, 0, &
        this%fragments_id, stat, msg)
      call create_series(this%path, gid, fr_where//'/', 'largest_fragments', H5T_STD_I64LE, &
        n_largest_fragments, this%largest_id, stat, msg)
    end block work
    if (eid >= 0) call h5gclose_f(eid, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
  end procedure h5_output_define_fracture_history

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_write_series
    integer :: p, k

    stat = 0
    msg = ''
    if (.not. allocated(this%reaction_id) .or. n == 0) return
    if (size(reactions, 1) /= 2 .or. size(reactions, 2) /= size(this%reaction_id) .or. &
        size(reactions, 3) < n) then
      stat = 1
      msg = 'iem_h5_output: write_series: the reactions do not match the series of '//this%path
      return
    end if
    if (this%fracture .neqv. (present(fragments) .and. present(largest))) then
      stat = 1
      msg = 'iem_h5_output: write_series: fragments and largest are needed for, and only '// &
        'for, a file with /history/fracture ('//this%path//')'
      return
    end if
    do p = 1, size(this%reaction_id)
      call append(this, this%reaction_id(p), trim(this%reaction_path(p)), 2, &
        this%n_series_samples, int(n, i8), stat, msg, r=[(reactions(:, p, k), k = 1, n)])
    end do
    if (this%fracture) then
      call append(this, this%fragments_id, fr_where//'/fragments', 0, this%n_series_samples, &
        int(n, i8), stat, msg, l=fragments(:n))
      call append(this, this%largest_id, fr_where//'/largest_fragments', n_largest_fragments, &
        this%n_series_samples, int(n, i8), stat, msg, l=[(largest(:, k), k = 1, n)])
    end if
    if (stat == 0) this%n_series_samples = this%n_series_samples + n
  end procedure h5_output_write_series

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_write_events
    integer(i8) :: nn
    integer :: m

    stat = 0
    msg = ''
    if (.not. this%fracture .or. n == 0) return
    nn = int(n, i8)
    m = merge(n, 0, this%rank == 0)
    if (this%rank == 0) then
      if (size(time) < n .or. size(x) < n .or. size(y) < n .or. size(kind) < n .or. &
          size(cell) < n .or. size(spring) < n) then
        stat = 1
        msg = 'iem_h5_output: write_events: fewer events given than n'
      end if
    end if
    ! rank 0 alone writes: the others select nothing (prepare_append)
    call append(this, this%event_id(1), fr_where//'/events/time', 0, this%n_events, nn, stat, &
      msg, r=time(:m))
    call append(this, this%event_id(2), fr_where//'/events/x', 0, this%n_events, nn, stat, &
      msg, r=x(:m))
    call append(this, this%event_id(3), fr_where//'/events/y', 0, this%n_events, nn, stat, &
      msg, r=y(:m))
    call append(this, this%event_id(4), fr_where//'/events/kind', 0, this%n_events, nn, stat, &
      msg, i=kind(:m))
    call append(this, this%event_id(5), fr_where//'/events/cell', 0, this%n_events, nn, stat, &
      msg, l=cell(:m))
    call append(this, this%event_id(6), fr_where//'/events/spring', 0, this%n_events, nn, &
      stat, msg, i=spring(:m))
    if (stat == 0) this%n_events = this%n_events + nn
  end procedure h5_output_write_events

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_reopen_series
    integer :: p, k, ierr
    integer(i8) :: have
    real(wp), allocatable :: times(:)
    logical :: exists

    stat = 0
    msg = ''
    call reaction_paths(this, names)
    this%fracture = fracture
    work: block
      call h5lexists_f(this%file_id, 'history/reactions', exists, ierr)
      if (failed(this%path, ierr, 'h5lexists_f', '/history/reactions', stat, msg)) exit work
      if (.not. exists) then
        stat = 1
        msg = 'iem_h5_output: '//this%path//' has no /history/reactions (written by an '// &
          'earlier iem): it cannot be continued'
        exit work
      end if
      do p = 1, size(names)
        call open_cut(this%file_id, this%path, 'history/reactions/'//trim(names(p)), &
          trim(this%reaction_path(p)), 2, n_samples, this%reaction_id(p), stat, msg)
      end do
      this%n_series_samples = n_samples
      if (.not. fracture) exit work
      call open_cut(this%file_id, this%path, 'history/fracture/fragments', &
        fr_where//'/fragments', 0, n_samples, this%fragments_id, stat, msg)
      call open_cut(this%file_id, this%path, 'history/fracture/largest_fragments', &
        fr_where//'/largest_fragments', n_largest_fragments, n_samples, this%largest_id, &
        stat, msg)
      ! the events logged up to the last sample kept (they are in time order)
      call open_cut(this%file_id, this%path, 'history/fracture/events/time', &
        fr_where//'/events/time', 0, -1_i8, this%event_id(1), stat, msg, have)
      if (stat /= 0) exit work
      allocate(times(have))
      if (have > 0) then
        call h5dread_f(this%event_id(1), this%real_mtype, times, [int(have, HSIZE_T)], ierr)
        if (failed(this%path, ierr, 'h5dread_f', fr_where//'/events/time', stat, msg)) exit work
      end if
      this%n_events = count(times <= t_last, kind=i8)
      do k = 1, n_event_series
        call open_cut(this%file_id, this%path, 'history/fracture/events/'//trim(event_names(k)), &
          fr_where//'/events/'//trim(event_names(k)), 0, this%n_events, this%event_id(k), &
          stat, msg)
      end do
    end block work
    if (stat /= 0) return
    call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
    if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) return
  end procedure h5_output_reopen_series

  !> The reaction series' paths (/history/reactions/<name>) and room for their datasets.
  subroutine reaction_paths(this, names)
    class(h5_output_t), intent(inout) :: this
    character(len=*), intent(in) :: names(:)
    integer :: p
    if (allocated(this%reaction_id)) deallocate(this%reaction_id)
    if (allocated(this%reaction_path)) deallocate(this%reaction_path)
    allocate(this%reaction_id(size(names)))
    this%reaction_id = -1
    allocate(character(len=len('/history/reactions/') + len(names)) :: &
      this%reaction_path(size(names)))
    do p = 1, size(names)
      this%reaction_path(p) = '/history/reactions/'//trim(names(p))
    end do
  end subroutine reaction_paths

  !> Append n samples (ncomp values each; 0: a 1-D series) after the first `old` of the
  !> series dset, from whichever of r (float64), l (int64), i (int32) is given, flat (rank 0
  !> writes; collective). Nothing once stat /= 0.
  subroutine append(this, dset, where, ncomp, old, n, stat, msg, r, l, i)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: dset
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: old, n
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    real(wp), intent(in), optional :: r(:)
    integer(i8), intent(in), optional :: l(:)
    integer, intent(in), optional :: i(:)
    integer(HID_T) :: fspace, mspace
    integer(HSIZE_T) :: dims(1)
    integer :: ierr
    ! what a rank that writes nothing (it selects nothing) passes instead of an empty buffer
    real(wp) :: r0(1)
    integer(i8) :: l0(1)
    integer :: i0(1)
    if (stat /= 0) return
    fspace = -1
    mspace = -1
    r0 = 0.0_wp
    l0 = 0
    i0 = 0
    call prepare_append(this%path, this%rank, dset, where, ncomp, old, n, fspace, mspace, &
      stat, msg)
    if (stat == 0) then
      if (present(r)) then
        dims = [size(r, kind=HSIZE_T)]
        if (dims(1) > 0) then
          call h5dwrite_f(dset, this%real_mtype, r, dims, ierr, mspace, fspace, this%xfer_id)
        else
          call h5dwrite_f(dset, this%real_mtype, r0, one, ierr, mspace, fspace, this%xfer_id)
        end if
      else if (present(l)) then
        dims = [size(l, kind=HSIZE_T)]
        if (dims(1) > 0) then
          call h5dwrite_f(dset, this%int_mtype, l, dims, ierr, mspace, fspace, this%xfer_id)
        else
          call h5dwrite_f(dset, this%int_mtype, l0, one, ierr, mspace, fspace, this%xfer_id)
        end if
      else
        dims = [size(i, kind=HSIZE_T)]
        if (dims(1) > 0) then
          call h5dwrite_f(dset, H5T_NATIVE_INTEGER, i, dims, ierr, mspace, fspace, &
            this%xfer_id)
        else
          call h5dwrite_f(dset, H5T_NATIVE_INTEGER, i0, one, ierr, mspace, fspace, &
            this%xfer_id)
        end if
      end if
      if (failed(this%path, ierr, 'h5dwrite_f', where, stat, msg)) continue
    end if
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)
  end subroutine append

end submodule iem_h5_output_series
