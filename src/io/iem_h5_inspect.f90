!> A serial, read-only look at an iem output file, for the checks of a restart before anything
!> is written (docs/output.md, "Exit status, checkpoints and continued runs").
module iem_h5_inspect
  use iem_kinds, only: wp, i8
  use hdf5, only: HID_T, HSIZE_T, h5open_f, h5eset_auto_f, h5fopen_f, h5fclose_f, &
    H5F_ACC_RDONLY_F, h5dopen_f, h5dclose_f, h5dget_space_f, h5dread_f, &
    h5sget_simple_extent_dims_f, h5sselect_hyperslab_f, h5screate_simple_f, h5sclose_f, &
    H5S_SELECT_SET_F, H5T_NATIVE_DOUBLE
  use iem_h5_layout, only: n_energies, energy_names
  implicit none
  private
  public :: h5_output_inspect

contains

  !> Opens path read-only on this rank alone (HDF5's error printing off) and returns how many frames
  !> and history samples it holds, the time of frame n_frames and history sample n_samples (time and
  !> the energies of iem_h5_layout) when it holds them; stat /= 0 with msg when it is not a readable
  !> iem output.
  subroutine h5_output_inspect(path, n_frames, n_samples, have_frames, have_samples, &
      frame_time, sample, stat, msg)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: n_frames, n_samples
    integer(i8), intent(out) :: have_frames, have_samples
    real(wp), intent(out) :: frame_time, sample(n_energies + 1)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(HID_T) :: file
    integer :: ierr
    logical :: ok
    integer :: k

    stat = 0
    msg = ''
    have_frames = 0
    have_samples = 0
    frame_time = 0.0_wp
    sample = 0.0_wp
    call h5open_f(ierr)
    if (ierr /= 0) then
      stat = 1
      msg = 'cannot be read (h5open_f failed)'
      return
    end if
    call h5eset_auto_f(0, ierr)
    call h5fopen_f(path, H5F_ACC_RDONLY_F, file, ierr)
    if (ierr /= 0) then
      stat = 1
      msg = 'cannot be opened as an HDF5 file'
      call h5eset_auto_f(1, ierr)
      return
    end if
    ok = .true.
    call read_at('frames/time', n_frames, have_frames, frame_time)
    call read_at('history/time', n_samples, have_samples, sample(1))
    do k = 1, n_energies
      call read_at('history/energy/'//trim(energy_names(k)), n_samples, have_samples, &
                   sample(1 + k))
    end do
    call h5fclose_f(file, ierr)
    call h5eset_auto_f(1, ierr)
    if (.not. ok) then
      stat = 1
      msg = 'is not an iem output of a dynamic run (no readable frames/time, history/time '// &
            'or history/energy)'
    end if

  contains

    !> Element i (1-based, when 1 <= i <= its length) of the 1D real dataset name, and its
    !> length n.
    subroutine read_at(name, i, n, v)
      character(len=*), intent(in) :: name
      integer(i8), intent(in) :: i
      integer(i8), intent(out) :: n
      real(wp), intent(inout) :: v
      integer(HID_T) :: dset, fspace, mspace
      integer(HSIZE_T) :: d(1), md(1)
      integer :: e, rank
      real(wp) :: buf(1)
      n = 0
      if (.not. ok) return
      call h5dopen_f(file, name, dset, e)
      if (e /= 0) then
        ok = .false.
        return
      end if
      call h5dget_space_f(dset, fspace, e)
      rank = -1
      if (e == 0) call h5sget_simple_extent_dims_f(fspace, d, md, rank)
      if (rank /= 1) then
        ok = .false.
      else
        n = int(d(1), i8)
        if (i >= 1 .and. i <= n) then
          call h5sselect_hyperslab_f(fspace, H5S_SELECT_SET_F, [int(i - 1, HSIZE_T)], [1_HSIZE_T], &
                                     e)
          call h5screate_simple_f(1, [1_HSIZE_T], mspace, e)
          call h5dread_f(dset, H5T_NATIVE_DOUBLE, buf, [1_HSIZE_T], e, mspace, fspace)
          if (e /= 0) ok = .false.
          v = buf(1)
          call h5sclose_f(mspace, e)
        end if
      end if
      call h5sclose_f(fspace, e)
      call h5dclose_f(dset, e)
    end subroutine read_at
  end subroutine h5_output_inspect
end module iem_h5_inspect
