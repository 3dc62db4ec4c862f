!> The image cell map of &geometry checked at read time: rank 0 reads the header of the
!> PBM/PGM file (iem_image) and checks it against the input; every rank then takes the grid
!> size from it. The pixels are read and checked by the ranks' strips when the body is
!> numbered (iem_body, classify_rows), so no rank reads the whole image.
module iem_input_image
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_INTEGER
  use iem_kinds, only: wp
  use iem_strings, only: itoa, rtoa
  use iem_config, only: config_t
  use iem_paths, only: why_not_readable
  use iem_image, only: image_t, read_image_rows
  use iem_input_files, only: bcast_message
  implicit none
  private
  public :: check_image

contains

  !> With &geometry image given: rank 0 reads its header and checks it (a readable PBM/PGM
  !> file, its size against nx, ny or cell_size, image_levels within 0..maxval); nx, ny are
  !> set to its width and height on every rank. Collective; stat /= 0
  !> and the same msg on every rank when something is wrong.
  subroutine check_image(cfg, comm, stat, msg)
    type(config_t), intent(inout) :: cfg
    type(MPI_Comm), intent(in) :: comm
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: rank, dims(2)
    real(wp) :: nn
    stat = 0
    msg = ''
    if (len_trim(cfg%geometry%image) == 0) return
    call MPI_Comm_rank(comm, rank)
    dims = 0
    if (rank == 0) call check_on_root(cfg, dims, msg)
    call bcast_message(msg, comm)
    call MPI_Bcast(dims, 2, MPI_INTEGER, 0, comm)
    if (len(msg) == 0) then
      cfg%geometry%nx = dims(1)
      cfg%geometry%ny = dims(2)
      nn = (real(dims(1), wp) + 1.0_wp)*(real(dims(2), wp) + 1.0_wp)
      if (nn > 2.0e9_wp) msg = "&geometry: image = '"//trim(cfg%geometry%image)//"': "// &
        itoa(dims(1))//' x '//itoa(dims(2))//' pixels give more than 2e9 nodes'
    end if
    stat = merge(1, 0, len(msg) > 0)
  end subroutine check_image

  subroutine check_on_root(cfg, dims, msg)
    type(config_t), intent(in) :: cfg
    integer, intent(out) :: dims(2)
    character(len=:), allocatable, intent(inout) :: msg
    character(len=:), allocatable :: path, head, why, prefix
    type(image_t) :: img
    integer :: stat, k
    path = trim(cfg%geometry%image)
    head = "&geometry: image = '"//path//"'"
    dims = 0
    why = why_not_readable(path)
    if (len(why) > 0) then
      msg = head//': '//why
      return
    end if
    call read_image_rows(path, 1, 0, img, stat, why)
    if (stat /= 0) then
      ! read_image names the file itself: keep only the reason
      prefix = "image '"//path//"': "
      if (len(why) >= len(prefix)) then
        if (why(1:len(prefix)) == prefix) why = why(len(prefix) + 1:)
      end if
      msg = head//': '//why
      return
    end if
    associate(o => cfg%geometry)
      if (o%nx /= 0 .and. o%nx /= img%width .or. o%ny /= 0 .and. o%ny /= img%height) then
        if (o%cell_size > 0.0_wp) then
          msg = '&geometry: cell_size = '//rtoa(o%cell_size)//' gives '//itoa(o%nx)//' x '// &
                itoa(o%ny)//' cells, but '//head(12:)//' has '//itoa(img%width)//' x '// &
                itoa(img%height)//' pixels (one pixel a cell): leave cell_size out'
        else
          msg = '&geometry: nx, ny = '//itoa(o%nx)//', '//itoa(o%ny)//' differ from the '// &
                itoa(img%width)//' x '//itoa(img%height)//' pixels of '//head(12:)// &
                ' (one pixel a cell): leave nx, ny out or make them equal'
        end if
        return
      end if
      do k = 1, size(o%image_levels)
        if (o%image_levels(k) > img%maxval) then
          msg = '&geometry: image_levels = '//itoa(o%image_levels(k))//' is above the '// &
                'maxval '//itoa(img%maxval)//' of '//head(12:)
          return
        end if
      end do
    end associate
    dims = [img%width, img%height]
  end subroutine check_on_root
end module iem_input_image
